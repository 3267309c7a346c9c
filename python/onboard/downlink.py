"""The ground's side of an onboard run: uplink the unit, then keep the run's record exactly.

:func:`supervise` sends the unit (again, unchanged, until the habitat answers: it answers a repeat
as the first time), then asks the habitat for the run's events above the last one the ground has
stored, each request waiting on the habitat for the next event. :class:`Downlink` stores each event
once, in order, in the ground's audit log, checking that it links to the one before and that its
hash is the habitat's: the ground's log is a verified copy of the habitat's chain, never a guess.
While the habitat does not answer, the ground says since when it has no news, and asks again.
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
import secrets
import signal
import time
from collections.abc import Awaitable, Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from pride.audit_chain import GENESIS, link_hash
from pride.audit_log import AuditLog
from pride.events import Event, EventKind
from pride.lint import CheckedProcedure
from rosbridge_wire.client import Endpoint, LinkError, RosbridgeClient

from .unit import ACTION_SERVICE, EVENTS_SERVICE, UPLINK_SERVICE, OperatorAction, Unit, sign

__all__ = ["Downlink", "DownlinkError", "Supervision", "build_unit", "supervise"]

log = logging.getLogger(__name__)

#: How long a request for events waits on the habitat for the next one.
POLL_WAIT_S = 10.0
#: How long an uplinked unit may take to reach the habitat and start, past the link's round trip.
UNIT_LIFETIME_S = 300.0
_RETRY_S = (1.0, 2.0, 5.0)


class DownlinkError(RuntimeError):
    """What came down is not the habitat's chain (a broken link between events, a changed event)."""


def _event(item: Any, run_id: str) -> tuple[Event, str, str, str]:
    """(event, its stored data text, prev hash, hash) of one downlinked event, each field checked."""
    if not isinstance(item, dict):
        raise DownlinkError(f"an event must be an object, not {type(item).__name__}")
    fields = {"run_id": str, "seq": int, "time": str, "actor": str, "kind": str, "data": str, "prev_hash": str}
    for name, kind in {**fields, "hash": str}.items():
        if not isinstance(item.get(name), kind) or isinstance(item.get(name), bool):
            raise DownlinkError(f"event field {name} must be {kind.__name__}: {str(item.get(name))[:60]!r}")
    if item["run_id"] != run_id:
        raise DownlinkError(f"an event of run {item['run_id'][:60]!r} came for run {run_id}")
    instruction = item.get("instruction")
    if instruction is not None and not isinstance(instruction, str):
        raise DownlinkError("event field instruction must be text or null")
    try:
        kind_ = EventKind(item["kind"])
        moment = datetime.fromisoformat(item["time"])
        data = json.loads(item["data"])
    except ValueError as exc:
        raise DownlinkError(f"event {item['seq']} cannot be read: {exc}") from None
    if not isinstance(data, dict):
        raise DownlinkError(f"event {item['seq']}'s data must be an object")
    event = Event(run_id, item["seq"], kind_, item["actor"], instruction, data, moment)
    return event, item["data"], item["prev_hash"], item["hash"]


class Downlink:
    """Stores an onboard run's events in the ground's audit log, each once, in order, verified."""

    def __init__(self, audit: AuditLog, run_id: str) -> None:
        self.audit = audit
        self.run_id = run_id
        stored = audit.stored_events(run_id)
        self.head_seq, self.head_hash = (stored[-1].seq, stored[-1].hash) if stored else (0, GENESIS)

    def take(self, items: Sequence[Any]) -> list[Event]:
        """Store what follows the ground's head; return the events newly stored.

        Events the ground has are passed over; one after a gap ends the batch (the next request
        asks from the head again).

        Raises:
            DownlinkError: an event does not link to the ground's head, or its hash is not its contents'.
        """
        stored: list[Event] = []
        for item in items:
            event, data, prev_hash, hash_ = _event(item, self.run_id)
            if event.seq <= self.head_seq:
                continue
            if event.seq != self.head_seq + 1:
                break
            if prev_hash != self.head_hash:
                raise DownlinkError(f"event {event.seq} does not link to event {self.head_seq} as the ground has it")
            expected = link_hash(
                prev_hash,
                run_id=event.run_id,
                seq=event.seq,
                time=event.time,
                actor=event.actor,
                kind=event.kind.value,
                instruction=event.instruction,
                data=data,
            )
            if expected != hash_:
                raise DownlinkError(f"event {event.seq}'s contents do not match its hash: not stored")
            self.audit.append(event)
            self.head_seq, self.head_hash = event.seq, hash_
            stored.append(event)
        return stored


def build_unit(
    checked: CheckedProcedure,
    *,
    run_id: str,
    binding: str,
    user: str,
    mode: str,
    values: Mapping[str, str],
    confirm_manual: bool,
    confirm_hazardous: bool,
    breakpoints: Sequence[str],
    lifetime_s: float,
    now: float,
) -> Unit:
    """The unit of a checked procedure: it and every sub-procedure it calls, by path relative to
    the folder that holds them all."""
    paths = [Path(checked.procedure.path).resolve(), *(Path(p) for p in checked.callees)]
    root = Path(os.path.commonpath([p.parent for p in paths]))
    files = {p.relative_to(root).as_posix(): p.read_text(encoding="utf-8") for p in paths}
    return Unit(
        run_id=run_id,
        procedure=paths[0].relative_to(root).as_posix(),
        files=files,
        binding=binding,
        user=user,
        mode=mode,
        issued_at=now,
        expires_at=now + lifetime_s,
        values=dict(values),
        confirm_manual=confirm_manual,
        confirm_hazardous=confirm_hazardous,
        breakpoints=tuple(breakpoints),
    )


@dataclass
class Supervision:
    """How a supervised onboard run ended, as the ground knows it."""

    status: str  # completed | stopped | interrupted | refused | expired | unreachable
    run_id: str
    message: str = ""


async def supervise(
    endpoint: Endpoint,
    unit: Unit,
    audit: AuditLog,
    *,
    on_event: Callable[[Event], None],
    say: Callable[[str], None],
    unattended: bool,
) -> Supervision:
    """Uplink ``unit`` and follow its run until it ends; Ctrl-C sends a Halt (again: a Stop).

    ``unattended`` (nobody at this terminal): a hold the unit did not answer stops the run, as an
    unattended ``caretaker run`` does on the ground; otherwise the run waits on the habitat.
    """
    assert endpoint.secret is not None  # the caller checked: units are signed with it
    secret = endpoint.secret
    client = RosbridgeClient(endpoint, name=f"caretaker-run-{unit.user}")
    client.start()
    loop = asyncio.get_running_loop()
    interrupts = 0

    async def act(action: str, **args: Any) -> None:
        operator = OperatorAction(
            key=f"{unit.run_id}/{action}/{secrets.token_hex(6)}",
            run_id=unit.run_id,
            action=action,
            user=unit.user,
            expires_at=time.time() + 60 + 2 * endpoint.one_way_delay,
            args=args,
        )
        text = operator.to_json()
        while time.time() < operator.expires_at:  # the same key again until answered: acted on once
            try:
                answer = await client.call(ACTION_SERVICE, {"action_json": text, "signature": sign(text, secret)})
                say(f"  {action.upper()} {answer['state'].lower()}: {answer['message']}")
                return
            except LinkError as exc:
                say(f"  {action.upper()} not answered yet ({exc}); sending it again")
                await asyncio.sleep(1.0)
        say(f"  {action.upper()} ran out before the habitat answered: not known whether it was acted on")

    def interrupt() -> None:
        nonlocal interrupts
        interrupts += 1
        if interrupts == 1:
            say("\n  HALT (Ctrl-C): sent to the habitat; Ctrl-C again stops the run")
            loop.create_task(act("halt", reason="Ctrl-C at the ground terminal"))
        else:
            say("\n  STOP (Ctrl-C twice): sent to the habitat")
            loop.create_task(act("stop", reason="Ctrl-C twice at the ground terminal"))

    loop.add_signal_handler(signal.SIGINT, interrupt)
    try:
        answer = await _uplink(client, unit, secret, say)
        if answer["state"] != "ACCEPTED":
            say(f"caretaker run: the habitat {answer['state'].lower()} the unit {answer['unit_hash'][:12]}:")
            say(str(answer["message"]))
            return Supervision(answer["state"].lower(), unit.run_id, str(answer["message"]))
        say(f"uplinked unit {answer['unit_hash']}: the habitat runs {unit.procedure} as run {unit.run_id}")
        say(f"READY run {unit.run_id}")

        async def waiting(where: str) -> None:
            say(f"  the onboard run waits for an operator: {where}")
            if unattended:
                say("  nobody at this terminal to answer: the run is stopped")
                await act("stop", reason=f"unattended run needs an operator at {where}")

        return await _follow(client, Downlink(audit, unit.run_id), on_event, say, waiting)
    finally:
        loop.remove_signal_handler(signal.SIGINT)
        await client.close()


async def _uplink(client: RosbridgeClient, unit: Unit, secret: str, say: Callable[[str], None]) -> Mapping[str, Any]:
    """The habitat's answer to the unit, asked again (the same unit) until one comes or it runs out."""
    text = unit.to_json()
    request = {"unit_json": text, "signature": sign(text, secret)}
    attempt = 0
    while True:
        left = unit.expires_at - time.time()
        if left <= 0:
            return {
                "state": "EXPIRED",
                "unit_hash": "",
                "message": "no answer from the habitat before the unit ran out",
            }
        try:
            await asyncio.wait_for(client.ready.wait(), left)
            return await client.call(UPLINK_SERVICE, request, timeout=client.call_timeout(60.0))
        except (LinkError, TimeoutError) as exc:
            say(f"  uplink not answered yet ({exc or 'not connected'}); sending the same unit again")
            await asyncio.sleep(_RETRY_S[min(attempt, len(_RETRY_S) - 1)])
            attempt += 1


async def _follow(
    client: RosbridgeClient,
    downlink: Downlink,
    on_event: Callable[[Event], None],
    say: Callable[[str], None],
    on_waiting: Callable[[str], Awaitable[None]],
) -> Supervision:
    """Store the run's events as they come, until it ended and the ground has them all; tell
    ``on_waiting`` once per hold the habitat leaves for an operator."""
    heard = time.time()
    silent = False
    waited = ""
    while True:
        try:
            values = await client.call(
                EVENTS_SERVICE,
                {"run_id": downlink.run_id, "after_seq": downlink.head_seq, "wait_s": POLL_WAIT_S, "max_events": 0},
                timeout=client.call_timeout(POLL_WAIT_S + 10.0),
            )
            items = json.loads(str(values.get("events_json", "[]")))
            if not isinstance(items, list):
                raise DownlinkError("events_json must be a list")
        except (LinkError, ValueError) as exc:
            if not silent:
                since = time.strftime("%H:%M:%S", time.gmtime(heard))
                say(f"  no news from the habitat since {since} UTC (at event {downlink.head_seq}): {exc}")
                silent = True
            await asyncio.sleep(1.0)
            continue
        heard = time.time()
        if silent:
            say(f"  the habitat answers again; catching up from event {downlink.head_seq + 1}")
            silent = False
        for event in downlink.take(items):
            on_event(event)
        status, head = str(values.get("status")), values.get("head_seq")
        waiting = str(values.get("waiting", ""))
        if waiting != waited and isinstance(head, int) and downlink.head_seq >= head:
            waited = waiting
            if waiting:
                await on_waiting(waiting)
        if status == "unknown":
            return Supervision("unknown", downlink.run_id, str(values.get("message")))
        if status != "active" and isinstance(head, int) and downlink.head_seq >= head:
            return Supervision(status, downlink.run_id)
