"""The ground's side of an onboard run: uplink the unit, then keep the run's record exactly.

:class:`OnboardSupervisor` sends the unit (again, unchanged, until the habitat answers: it answers a repeat
as the first time) and, right behind it, requests for the run's events, kept going so that one is
always waiting on the habitat (:mod:`onboard.follow_requests`): the ground hears of each event, the
run's end among them, one light time after it happened. :class:`Downlink` stores each event
once, in order, in the ground's audit log, checking that it links to the one before and that its
hash is the habitat's: the ground's log is a verified copy of the habitat's chain, never a guess.
While the habitat does not answer, the ground says since when it has no news, and asks again.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import dataclasses
import json
import logging
import os
import secrets
import signal
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from pride.accepted_proposal import AcceptedProposal
from pride.approvals import ApprovalPolicy, CarriedApproval, approval_points, missing_approvals_text
from pride.event_payloads import payload_from_json
from pride.events import Event, EventKind
from pride.executive import Mode
from pride.run_section import RunSection
from pride.run_setup import RunSetup
from pride.run_version import RunVersion
from procedure_language.lint import CheckedProcedure
from records.audit_chain import GENESIS, link_hash
from records.audit_log import AuditLog
from rosbridge_wire.client import Endpoint, LinkError, RosbridgeClient
from rosbridge_wire.light_time import LightTime

from .follow_requests import FollowAnswer, FollowRequests
from .unit import ACTION_SERVICE, UPLINK_SERVICE, OperatorAction, Unit, sign

__all__ = [
    "ActionOutcome",
    "ActionTiming",
    "Downlink",
    "DownlinkError",
    "HabitatNews",
    "OnboardSupervisor",
    "Supervision",
    "build_unit",
    "unit_for_run",
]

log = logging.getLogger(__name__)

#: How long an uplinked unit may take to reach the habitat and start, past the link's round trip.
UNIT_LIFETIME_S = 300.0
_RETRY_S = (1.0, 2.0, 5.0)
#: What accepting a unit may take on the habitat before it answers: its checks and starting the run's
#: executive, a JVM among them, on a loaded machine (past a minute under the suite's load). A unit
#: not answered in time is sent again, but across a long link each try costs a round trip.
UNIT_WORK_S = 120.0
#: What acting on an operator's action may take on the habitat before it answers (a loaded machine).
ACTION_WORK_S = 10.0
#: How long past its round trip an action may still be taken: sent again under its key meanwhile.
ACTION_SPARE_S = 60.0


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
        data = payload_from_json(kind_, json.loads(item["data"]))  # EventDataError: a field of the wrong type
    except ValueError as exc:
        raise DownlinkError(f"event {item['seq']} cannot be read: {exc}") from None
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
        """Store what follows the ground's head, in one transaction; return the events newly stored.

        Events the ground has are passed over; one after a gap ends the batch (the next request
        asks from the head again).

        Raises:
            DownlinkError: an event cannot be read, does not link to the ground's head, or its hash
                is not its contents' (those before it are stored).
        """
        batch: list[Event] = []
        head_seq, head_hash = self.head_seq, self.head_hash
        problem: DownlinkError | None = None
        for item in items:
            try:
                event, data, prev_hash, hash_ = _event(item, self.run_id)
            except DownlinkError as exc:
                problem = exc
                break
            if event.seq <= head_seq:
                continue
            if event.seq != head_seq + 1:
                break
            if prev_hash != head_hash:
                problem = DownlinkError(f"event {event.seq} does not link to event {head_seq} as the ground has it")
                break
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
                problem = DownlinkError(f"event {event.seq}'s contents do not match its hash: not stored")
                break
            batch.append(event)
            head_seq, head_hash = event.seq, hash_
        self.audit.append_all(batch)
        self.head_seq, self.head_hash = head_seq, head_hash
        if problem is not None:
            raise problem
        return batch


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
    policy: ApprovalPolicy,
    version: RunVersion | None = None,
    approver: str | None = None,
    section: RunSection | None = None,
    in_transit: float = 0.0,
    proposal: AcceptedProposal | None = None,
) -> Unit:
    """The unit of a checked procedure: it and every sub-procedure it calls, by path relative to
    the folder that holds them all; under ``policy``, ``approver``'s approval of each command that
    needs one, given now and good from ``in_transit`` s on (how long the unit may take to reach the
    habitat); ``section``: the part of the procedure to run (checked here first); ``proposal``:
    the agent's proposal an operator accepted to start it.

    Raises:
        ValueError: a command needs approval and no ``approver`` is given, or it is ``user``.
        SectionError: the section cannot start (what the skipped steps bind is not given).
    """
    if section is not None:
        section.check(checked)
    paths = [Path(checked.procedure.path).resolve(), *(Path(p).resolve() for p in checked.callees)]
    root = Path(os.path.commonpath([p.parent for p in paths]))
    files = {p.relative_to(root).as_posix(): p.read_text(encoding="utf-8") for p in paths}
    points = approval_points(checked, policy)
    if points and approver is None:
        raise ValueError(
            f"{missing_approvals_text(points, paths[0], policy)}: the habitat cannot wait a round trip for "
            "each, so a second operator approves them before the unit goes up"
        )
    approvals = tuple(
        CarriedApproval.given(
            point, point.procedure.relative_to(root).as_posix(), user, str(approver), policy, in_transit=in_transit
        )
        for point in points
    )
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
        version=version,
        approvals=approvals,
        section={"from": section.start, "to": section.stop} if section else None,
        proposal=proposal,
    )


def unit_for_run(
    setup: RunSetup,
    endpoint: Endpoint,
    *,
    binding: str,
    user: str,
    mode: Mode,
    values: Mapping[str, str],
    approver: str | None,
    proposal: AcceptedProposal | None = None,
    confirm_manual: bool = False,
    confirm_hazardous: bool = False,
    breakpoints: Sequence[str] = (),
    section: RunSection | None = None,
    lifetime_s: float = UNIT_LIFETIME_S,
) -> Unit:
    """The unit of the run ``setup`` prepares, going up over ``endpoint``: it lives ``lifetime_s``
    past what the link's light time takes to connect and answer, and its approvals hold from when
    the light time lets it arrive (:func:`build_unit`, whose errors it raises). A terminal's
    ``caretaker run --onboard`` and a console's start on the habitat build it alike."""
    light = endpoint.light_time
    return build_unit(
        setup.checked,
        run_id=setup.run_id,
        binding=binding,
        user=user,
        mode=mode.value,
        values=values,
        confirm_manual=confirm_manual,
        confirm_hazardous=confirm_hazardous,
        breakpoints=breakpoints,
        lifetime_s=lifetime_s + light.connect_within + light.round_trip,
        now=time.time(),
        version=setup.version,
        policy=setup.side.approvals,
        approver=approver,
        section=section,
        in_transit=light.uplink_within,
        proposal=proposal,
    )


@dataclass
class Supervision:
    """How a supervised onboard run ended, as the ground knows it."""

    status: str  # completed | stopped | interrupted | refused | expired | unreachable | unknown | detached
    run_id: str
    message: str = ""


@dataclass(frozen=True)
class HabitatNews:
    """What the ground last heard of an onboard run, for views that show it live.

    ``snapshot`` is the onboard executive's state (``Snapshot.to_json``) as of an event the ground
    has stored (None until one came); ``silent_since`` (ground clock, epoch s) is set while the
    habitat does not answer: the views then say "no news since", and never fill in.
    """

    snapshot: Mapping[str, Any] | None
    habitat_time: str  # the habitat's clock at its last answer (ISO 8601), "" before one
    heard: float  # ground clock (epoch s) of the last answer
    waiting: str  # "N: why" while the run holds for an operator
    silent_since: float | None = None


@dataclass(frozen=True)
class ActionOutcome:
    """The habitat's answer to an operator's action: DONE | REFUSED | EXPIRED, or UNKNOWN when
    none came before the action ran out (it may or may not have been acted on)."""

    state: str
    message: str


@dataclass(frozen=True)
class ActionTiming:
    """When an operator's action went up and what the link's light time makes of it (ground clock,
    epoch s). Nothing here is a constant wait: each is :meth:`LightTime.answer_within` of the link,
    so an action at 600 s one way is on its way for 20 minutes, not unknown after 30 s."""

    sent: float
    expected_at: float  # its answer is due: sent + round trip + the habitat's work
    expires_at: float  # the habitat refuses it after this (its lifetime); sent again until then
    gives_up_at: float  # the last try before it expired is answered by then, or never

    @classmethod
    def of(cls, light_time: LightTime, sent: float) -> ActionTiming:
        expires_at = sent + light_time.answer_within(ACTION_SPARE_S)
        return cls(
            sent=sent,
            expected_at=sent + light_time.answer_within(ACTION_WORK_S),
            expires_at=expires_at,
            gives_up_at=expires_at + light_time.answer_within(ACTION_WORK_S),
        )


class OnboardSupervisor:
    """Uplinks ``unit`` and follows its run until it ends (:meth:`run`, or :meth:`supervise` on a
    session a long-lived supervisor keeps open); operators' actions go up keyed (:meth:`act`, or
    :meth:`act_from_thread` from a console's thread).

    ``unattended`` (nobody at this terminal): a hold the unit did not answer stops the run, as an
    unattended ``caretaker run`` does on the ground; otherwise the run waits on the habitat for an
    operator (at this terminal's Ctrl-C, or at a console). ``on_news`` is called on the event loop
    after each answer of the habitat and when it falls silent.
    """

    def __init__(
        self,
        endpoint: Endpoint,
        unit: Unit,
        audit: AuditLog,
        *,
        on_event: Callable[[Event], None],
        say: Callable[[str], None],
        unattended: bool,
        on_news: Callable[[HabitatNews], None] | None = None,
        operator: str | None = None,
        client: RosbridgeClient | None = None,
        on_uplinked: Callable[[str], None] | None = None,
    ) -> None:
        """``operator``: who acts from this terminal (Ctrl-C's Halt, an unattended stop); by default
        the unit's user (a supervisor that attached acts as its own). ``client``: a session to the
        habitat that its owner keeps open (``caretaker supervise``); by default one of its own,
        opened and closed with :meth:`run` or :meth:`attach`. ``on_uplinked`` hears the unit's hash
        when the habitat accepted it."""
        if endpoint.secret is None:
            raise ValueError("an onboard unit is signed with the link's secret: the endpoint has none")
        self.endpoint = endpoint
        self.unit = unit
        self._secret = endpoint.secret
        self._downlink = Downlink(audit, unit.run_id)
        self._on_event = on_event
        self._say = say
        self._unattended = unattended
        self._on_news = on_news
        self._operator = operator or unit.user
        self._own_client = client is None
        self._client = client or RosbridgeClient(endpoint, name=f"caretaker-run-{self._operator}")
        self._loop: asyncio.AbstractEventLoop | None = None
        self._interrupts = 0
        self._on_uplinked = on_uplinked

    async def run(self) -> Supervision:
        """Uplink, then follow the run to its end; Ctrl-C sends a Halt (again: a Stop)."""
        return await self._supervising(attaching=False)

    async def attach(self) -> Supervision:
        """Follow a run already on the habitat (its supervisor stopped) to its end, as :meth:`run`
        does after the uplink: the ground's record is caught up from the last event it stored, each
        event checked against the one before, hash for hash."""
        return await self._supervising(attaching=True)

    async def _supervising(self, *, attaching: bool) -> Supervision:
        """:meth:`supervise` at a terminal: Ctrl-C halts the run, SIGTERM ends supervision."""
        loop = asyncio.get_running_loop()
        if self._own_client:
            self._client.start()
        detached = asyncio.Event()
        loop.add_signal_handler(signal.SIGINT, self._interrupt)
        loop.add_signal_handler(signal.SIGTERM, detached.set)
        try:
            return await self.supervise(attaching=attaching, detach=detached)
        finally:
            loop.remove_signal_handler(signal.SIGINT)
            loop.remove_signal_handler(signal.SIGTERM)
            if self._own_client:
                await self._client.close()

    async def supervise(self, *, attaching: bool = False, detach: asyncio.Event | None = None) -> Supervision:
        """Uplink the unit (``attaching``: catch up with a run already on the habitat) and follow
        the run to its end, or until ``detach`` is set: that ends supervision, never the run (it goes
        on on the habitat, and ``caretaker run --attach`` follows it again)."""
        loop = self._loop = asyncio.get_running_loop()
        supervising = loop.create_task(self._caught_up() if attaching else self._uplinked())
        ending = loop.create_task((detach or asyncio.Event()).wait())
        try:
            await asyncio.wait((supervising, ending), return_when=asyncio.FIRST_COMPLETED)
            if supervising.done():
                return supervising.result()
            supervising.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await supervising
            self._say(f"  supervision stopped at event {self._downlink.head_seq}: the run goes on on the habitat")
            return Supervision("detached", self.unit.run_id, "supervision stopped; the run goes on on the habitat")
        finally:
            ending.cancel()

    def _requests(self) -> FollowRequests:
        light_time = self.endpoint.light_time
        return FollowRequests(self._client, self.unit.run_id, light_time, lambda: self._downlink.head_seq)

    async def _caught_up(self) -> Supervision:
        await self._client.ready.wait()  # reconnecting until the link lets it through
        self._say(f"attached to onboard run {self.unit.run_id}: catching up from event {self._downlink.head_seq + 1}")
        self._say(f"READY run {self.unit.run_id}")
        requests = self._requests()
        requests.catch_up()
        requests.start()
        return await self._follow(requests, accepted_at=None)

    async def _uplinked(self) -> Supervision:
        self._say(f"the unit of run {self.unit.run_id} goes up to {self.endpoint.url}")
        requests = self._requests()
        try:
            answer = await _uplink(self._client, self.unit, self._secret, self._say, sent=requests.start)
        except BaseException:
            requests.close()
            raise
        accepted_at = asyncio.get_running_loop().time()
        if answer["state"] != "ACCEPTED":
            requests.close()
            self._say(f"caretaker run: the habitat {answer['state'].lower()} the unit {answer['unit_hash'][:12]}:")
            self._say(str(answer["message"]))
            return Supervision(answer["state"].lower(), self.unit.run_id, str(answer["message"]))
        unit = self.unit
        self._say(f"uplinked unit {answer['unit_hash']}: the habitat runs {unit.procedure} as run {unit.run_id}")
        if self._on_uplinked is not None:
            self._on_uplinked(str(answer["unit_hash"]))
        self._say(f"READY run {self.unit.run_id}")
        return await self._follow(requests, accepted_at=accepted_at)

    async def act(self, action: str, user: str, *, timing: ActionTiming | None = None, **args: Any) -> ActionOutcome:
        """Send an operator's action up, under one key until the habitat answers or it runs out
        (``timing``: when it was sent, as :meth:`act_from_thread` told the console; default now)."""
        timing = timing or ActionTiming.of(self.endpoint.light_time, time.time())
        operator = OperatorAction(
            key=f"{self.unit.run_id}/{action}/{secrets.token_hex(6)}",
            run_id=self.unit.run_id,
            action=action,
            user=user,
            expires_at=timing.expires_at,
            args=args,
        )
        text = operator.to_json()
        request = {"action_json": text, "signature": sign(text, self._secret)}
        while time.time() < operator.expires_at:  # the same key again until answered: acted on once
            try:
                answer = await self._client.call(ACTION_SERVICE, request)
                outcome = ActionOutcome(str(answer["state"]), str(answer["message"]))
                self._say(f"  {action.upper()} {outcome.state.lower()}: {outcome.message}")
                return outcome
            except LinkError as exc:
                self._say(f"  {action.upper()} not answered yet ({exc}); sending it again")
                await asyncio.sleep(1.0)
        message = f"{action} ran out before the habitat answered: not known whether it was acted on"
        self._say(f"  {message}")
        return ActionOutcome("UNKNOWN", message)

    def act_from_thread(
        self,
        action: str,
        user: str,
        args: Mapping[str, Any],
        on_its_way: Callable[[ActionTiming], None] | None = None,
    ) -> ActionOutcome:
        """:meth:`act` from another thread (a console's forwarded request), waiting for its answer as
        long as the light time makes it take; ``on_its_way`` hears when it went up and when its
        answer is due, before that answer (a console says so meanwhile)."""
        loop = self._loop
        if loop is None:
            return ActionOutcome("REFUSED", "the run is not uplinked yet: not sent")
        timing = ActionTiming.of(self.endpoint.light_time, time.time())
        sending = self.act(action, user, timing=timing, **args)
        try:
            future = asyncio.run_coroutine_threadsafe(sending, loop)
        except RuntimeError:  # the loop has ended: supervision is over
            sending.close()
            return ActionOutcome("REFUSED", "the ground no longer supervises this run: not sent")
        if on_its_way is not None:
            on_its_way(timing)
        try:
            return future.result(max(0.0, timing.gives_up_at - time.time()) + 1.0)
        except concurrent.futures.CancelledError:  # supervision ended while it was being sent
            return ActionOutcome("UNKNOWN", "supervision ended while it was being sent (see the log)")
        except TimeoutError:
            given_up = datetime.fromtimestamp(timing.gives_up_at, UTC).strftime("%H:%M:%S UTC")
            return ActionOutcome("UNKNOWN", f"sent; no answer from the habitat by {given_up} (see the run's log)")

    def _interrupt(self) -> None:
        self._interrupts += 1
        assert self._loop is not None
        user = self._operator
        if self._interrupts == 1:
            self._say("\n  HALT (Ctrl-C): sent to the habitat; Ctrl-C again stops the run")
            self._loop.create_task(self.act("halt", user, reason="Ctrl-C at the ground terminal"))
        else:
            self._say("\n  STOP (Ctrl-C twice): sent to the habitat")
            self._loop.create_task(self.act("stop", user, reason="Ctrl-C twice at the ground terminal"))

    async def _waiting(self, where: str) -> None:
        self._say(f"  the onboard run waits for an operator: {where}")
        if self._unattended:
            self._say("  nobody at this terminal to answer: the run is stopped")
            await self.act("stop", self._operator, reason=f"unattended run needs an operator at {where}")

    def _news(self, news: HabitatNews) -> None:
        if self._on_news is not None:
            self._on_news(news)

    async def _follow(self, requests: FollowRequests, *, accepted_at: float | None) -> Supervision:
        """Store the run's events as they come, until it ended and the ground has them all
        (``accepted_at``: when the habitat accepted the unit, on the loop's clock; a request that
        went before it may have reached the habitat before the unit did)."""
        downlink = self._downlink
        heard = time.time()
        last = HabitatNews(None, "", heard, "")
        silent = False
        waited = ""
        try:
            while True:
                try:
                    answer: FollowAnswer = await requests.next()
                except LinkError as exc:
                    if not silent:
                        since = time.strftime("%H:%M:%S", time.gmtime(heard))
                        self._say(f"  no news from the habitat since {since} UTC (at event {downlink.head_seq}): {exc}")
                        silent = True
                        last = dataclasses.replace(last, silent_since=heard)
                        self._news(last)
                    await asyncio.sleep(1.0)
                    requests.catch_up()  # what the lost answers carried
                    continue
                values = answer.values
                status, head = str(values.get("status")), values.get("head_seq")
                # one that went before the unit was accepted may have found no run yet (its events count)
                early = status == "unknown" and accepted_at is not None and answer.sent_at < accepted_at
                heard = time.time()
                if silent:
                    self._say(f"  the habitat answers again; catching up from event {downlink.head_seq + 1}")
                    silent = False
                # off the loop: a supervisor follows many runs on it, and each store waits for its commit
                for event in await asyncio.to_thread(downlink.take, answer.events):
                    self._on_event(event)
                waiting = str(values.get("waiting", ""))
                caught_up = isinstance(head, int) and downlink.head_seq >= head
                if not caught_up:
                    requests.catch_up()  # a gap: an answer lost with its connection, or taken by another
                snapshot = _snapshot(values.get("snapshot_json"), downlink.head_seq) or last.snapshot
                last = HabitatNews(snapshot, str(values.get("habitat_time", "")), heard, waiting)
                self._news(last)
                if early:
                    continue
                if waiting != waited and caught_up:
                    waited = waiting
                    if waiting:
                        await self._waiting(waiting)
                if status == "unknown":
                    return Supervision("unknown", downlink.run_id, str(values.get("message")))
                if status != "active" and caught_up:
                    return Supervision(status, downlink.run_id)
        finally:
            requests.close()


def _snapshot(text: Any, head_seq: int) -> Mapping[str, Any] | None:
    """The onboard executive's state as the habitat sent it, if it is an object and not ahead of the
    events the ground has stored (shown once they are); None otherwise (the view keeps the last)."""
    if not text:
        return None
    try:
        value = json.loads(str(text))
    except ValueError:
        log.warning("the habitat's snapshot_json is not JSON: %.80r", text)
        return None
    if not isinstance(value, dict) or not isinstance(value.get("last_seq", 0), int):
        log.warning("the habitat's snapshot_json is not a snapshot: %.80r", text)
        return None
    return value if value.get("last_seq", 0) <= head_seq else None


async def _uplink(
    client: RosbridgeClient, unit: Unit, secret: str, say: Callable[[str], None], *, sent: Callable[[], None]
) -> Mapping[str, Any]:
    """The habitat's answer to the unit, asked again (the same unit) until one comes or it runs out;
    ``sent`` is called as each try goes (the requests for the run's events follow it)."""
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
            await asyncio.wait_for(client.opened.wait(), left)  # right behind the login
            answer = asyncio.ensure_future(
                client.call(UPLINK_SERVICE, request, timeout=client.call_timeout(UNIT_WORK_S))
            )
            sent()
            return await answer
        except (LinkError, TimeoutError) as exc:
            say(f"  uplink not answered yet ({exc or 'not connected'}); sending the same unit again")
            await asyncio.sleep(_RETRY_S[min(attempt, len(_RETRY_S) - 1)])
            attempt += 1
