"""The cases of the ``clients`` profile: what the scripted server does in each, and the verdict.

Each case has a WebSocket path of its own (``/clients.N``): the client under test connects there
for that case, and a reconnection comes back to the same path, so the server knows which case a
connection belongs to without any hook in the client. The driver reports what the program got
from its client by calling ``/interop/report`` on a second connection (``/report``); a report may
hold back the server (the call is answered once the scenario has played the next step), which
keeps every step event-driven: the server drops a connection once the driver says what it
registered, and sends a late answer once the driver says the call timed out.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import Any, Protocol

from interop.outcome import Frame, Outcome

__all__ = ["CASES", "CaseRun", "Peer", "Scenario", "scenarios"]

log = logging.getLogger(__name__)

ECHO = "/interop/echo"
"""A service every case answers at once with ``{"data": args.data}``."""


class Peer(Protocol):
    """One WebSocket connection of the client under test, as a scenario sees it."""

    number: int  # 1 for the first connection of the case, 2 for the first reconnection, ...

    async def send(self, message: Mapping[str, Any]) -> None: ...

    async def close(self, code: int, reason: str) -> None: ...

    def drop(self) -> None:
        """End the TCP connection at once, without a close frame (a network failure)."""


class CaseRun:
    """One case against one client: its frames, its connections, and what the driver reported."""

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.started: float | None = None  # monotonic time of the first connection
        self.frames: list[Frame] = []
        self.connections: list[dict[str, Any]] = []
        self.observed: dict[str, Any] = {}
        self.ended = asyncio.Event()
        self.finished_at: float | None = None  # seconds after the start when the driver said done
        self._update = asyncio.Condition()

    def elapsed(self) -> float:
        return 0.0 if self.started is None else time.monotonic() - self.started

    def record(self, direction: str, text: str) -> None:
        self.frames.append(Frame(direction, round(self.elapsed(), 4), text))

    async def report(self, update: Mapping[str, Any]) -> None:
        """Merge a driver's report (the case ends with :meth:`end`, once the scenario has seen it)."""
        async with self._update:
            self.observed.update(update)
            self._update.notify_all()

    def end(self) -> None:
        self.finished_at = self.elapsed()
        self.ended.set()

    async def reported(self, key: str, timeout: float) -> bool:
        """Wait until the driver reported ``key``; False when it did not within ``timeout``."""
        async with self._update:
            try:
                await asyncio.wait_for(self._update.wait_for(lambda: key in self.observed), timeout)
            except TimeoutError:
                return False
            return True


def call_args(message: Mapping[str, Any]) -> dict[str, Any]:
    """A call's ``args`` as an object (a list or anything else counts as no arguments)."""
    args = message.get("args")
    return dict(args) if isinstance(args, Mapping) else {}


def answer(message: Mapping[str, Any], values: Any, *, result: bool = True) -> dict[str, Any]:
    """The ``service_response`` to a ``call_service`` (P-SRV-1), its ``id`` copied when it had one."""
    response: dict[str, Any] = {"op": "service_response", "service": message.get("service"), "values": values}
    response["result"] = result
    if "id" in message:
        response["id"] = message["id"]
    return response


def short(value: Any, limit: int = 60) -> str:
    """A value for an observed text: long strings by their length and start."""
    if isinstance(value, str) and len(value) > limit:
        return f"a string of {len(value)} characters starting {value[:20]!r}"
    return repr(value)


class Scenario(ABC):
    """A case: how the server answers the client, and how the evidence is judged."""

    case = ""
    title = ""
    statements: tuple[str, ...] = ()
    expected = ""
    time_limit = 8.0
    """Seconds from the case's first connection until it is judged with whatever was reported."""

    async def on_open(self, run: CaseRun, peer: Peer) -> None:  # noqa: B027 (optional: most cases ignore it)
        """A connection of the client under test to this case's path has opened."""

    async def on_message(self, run: CaseRun, peer: Peer, message: Mapping[str, Any]) -> bool:
        """A message of the client; True when the scenario answered it (else the server's defaults do)."""
        return False

    async def on_report(self, run: CaseRun, update: Mapping[str, Any]) -> dict[str, Any]:
        """The driver reported; the report's call is answered when this returns, with these values."""
        return {}

    @abstractmethod
    def judge(self, run: CaseRun) -> tuple[Outcome, str]:
        """The case's outcome from the evidence, and why in words."""


def no_report(run: CaseRun) -> tuple[Outcome, str] | None:
    """FAILED when the driver never said it was done with the case (the client hung or crashed)."""
    if run.started is None:
        return Outcome.FAILED, "the client never connected to this case"
    if not run.observed.get("done"):
        return Outcome.FAILED, f"no final report from the driver within {run.scenario.time_limit:.0f} s"
    return None


class OutOfOrder(Scenario):
    case = "clients.1"
    title = "Two calls in flight answered in reverse order"
    statements = ("P-GEN-2", "P-SRV-1", "P-CLI-1")
    expected = 'the call with {"data":"first"} gets "first" and the other "second", though answered second-first'
    HOLD = 4.0  # how long the first call waits for a second one in flight

    def __init__(self) -> None:
        self.pending: list[tuple[Peer, Mapping[str, Any]]] = []
        self.most_in_flight = 0
        self.timer: asyncio.Task[None] | None = None

    async def on_message(self, run: CaseRun, peer: Peer, message: Mapping[str, Any]) -> bool:
        if message.get("op") != "call_service" or message.get("service") != ECHO:
            return False
        self.pending.append((peer, message))
        self.most_in_flight = max(self.most_in_flight, len(self.pending))
        if len(self.pending) >= 2:
            await self._answer_pending()
        elif self.timer is None:
            self.timer = asyncio.get_running_loop().create_task(self._answer_late())
        return True

    async def _answer_late(self) -> None:
        await asyncio.sleep(self.HOLD)  # a client that sends one call at a time still gets its answers
        await self._answer_pending()

    async def _answer_pending(self) -> None:
        pending, self.pending = self.pending, []
        for peer, message in reversed(pending):
            await peer.send(answer(message, {"data": call_args(message).get("data")}))

    def judge(self, run: CaseRun) -> tuple[Outcome, str]:
        if (missing := no_report(run)) is not None:
            return missing
        first, second = run.observed.get("first"), run.observed.get("second")
        got = f"the first call got {short(first)}, the second {short(second)}"
        if first != "first" or second != "second":
            return Outcome.FAILED, got
        if self.most_in_flight < 2:
            return Outcome.INFORMATIONAL, f"{got}; the client sent the second call only after the first was answered"
        return Outcome.OK, f"{got} (both in flight, answered in reverse order)"


class Fragmented(Scenario):
    case = "clients.2"
    title = "A message delivered in three fragments"
    statements = ("P-FRAG-1", "P-PUB-3", "P-CLI-2")
    expected = 'the program gets the whole message, then the plain message "after"'
    TOPIC = "/interop/fragmented"
    DATA = "fragmented:" + "0123456789" * 300
    PARTS = 3

    def __init__(self) -> None:
        self.sent = False

    async def on_message(self, run: CaseRun, peer: Peer, message: Mapping[str, Any]) -> bool:
        if message.get("op") == "subscribe" and message.get("topic") == self.TOPIC and not self.sent:
            self.sent = True
            text = json.dumps({"op": "publish", "topic": self.TOPIC, "msg": {"data": self.DATA}})
            size = -(-len(text) // self.PARTS)
            for num in range(self.PARTS):
                piece = text[num * size : (num + 1) * size]
                await peer.send(
                    {"op": "fragment", "id": "interop-fragments", "data": piece, "num": num, "total": self.PARTS}
                )
            await peer.send({"op": "publish", "topic": self.TOPIC, "msg": {"data": "after"}})
        return False

    def judge(self, run: CaseRun) -> tuple[Outcome, str]:
        if (missing := no_report(run)) is not None:
            return missing
        received = run.observed.get("received")
        if not isinstance(received, list):
            return Outcome.FAILED, f"the driver reported no list of messages: {short(received)}"
        got = "the program got " + (", ".join(short(item, 30) for item in received) or "nothing")
        if received == [self.DATA, "after"]:
            return Outcome.OK, got
        if received == ["after"]:
            return Outcome.UNIMPLEMENTED, f"{got}: the fragments were dropped, the connection kept"
        return Outcome.FAILED, got


class Status(Scenario):
    case = "clients.3"
    title = "A status message the client did not ask for"
    statements = ("P-STAT-2", "P-CLI-3")
    expected = 'the client keeps its connection and subscription: the program gets the message "after"'
    TOPIC = "/interop/status_after"

    def __init__(self) -> None:
        self.sent = False

    async def on_message(self, run: CaseRun, peer: Peer, message: Mapping[str, Any]) -> bool:
        if message.get("op") == "subscribe" and message.get("topic") == self.TOPIC and not self.sent:
            self.sent = True
            status = {"op": "status", "level": "error", "msg": "interop: a status message"}
            await peer.send(status)
            await peer.send({"op": "publish", "topic": self.TOPIC, "msg": {"data": "after"}})
        return False

    def judge(self, run: CaseRun) -> tuple[Outcome, str]:
        if (missing := no_report(run)) is not None:
            return missing
        received = run.observed.get("received")
        told = run.observed.get("status")
        how = f"the program was told: {short(told)}" if told else "the program was not told of the status"
        if received == ["after"]:
            return Outcome.OK, f"kept going ({how})"
        return Outcome.FAILED, f"the program got {short(received)} instead of ['after'] ({how})"


class Dropped(Scenario):
    case = "clients.4"
    title = "A dropped connection: reconnect, subscribe and advertise again"
    statements = ("P-SUB-1", "P-ASRV-1", "P-CLI-4")
    expected = (
        "the client reconnects and sends every subscribe/advertise/advertise_service again; the program "
        'gets the message "after-reconnect", and the re-advertised service answers'
    )
    TOPIC = "/interop/drop"
    SERVICE = "/interop/drop_service"
    REGISTRATIONS = ("subscribe", "advertise", "advertise_service")
    RECONNECT_WINDOW = 5.0  # seconds after the drop
    RESTORE_WINDOW = 4.0  # seconds after the reconnection for every registration to come again
    time_limit = 20.0

    def __init__(self) -> None:
        self.registered: dict[int, set[str]] = {}
        self.peers: dict[int, Peer] = {}
        self.dropped_at: float | None = None
        self.reconnected_at: float | None = None
        self.reconnected = asyncio.Event()
        self.restored = asyncio.Event()
        self.served: Any = None
        self.service_answered = asyncio.Event()
        self.changed = asyncio.Condition()

    async def on_open(self, run: CaseRun, peer: Peer) -> None:
        self.peers[peer.number] = peer
        if peer.number == 2:
            self.reconnected_at = run.elapsed()
            self.reconnected.set()

    async def on_message(self, run: CaseRun, peer: Peer, message: Mapping[str, Any]) -> bool:
        op = message.get("op")
        if op in self.REGISTRATIONS:
            name = message.get("service") if op == "advertise_service" else message.get("topic")
            self.registered.setdefault(peer.number, set()).add(f"{op} {name}")
            if peer.number >= 2 and self.registered.get(1, set()) <= self.registered[peer.number]:
                self.restored.set()
            async with self.changed:
                self.changed.notify_all()
        elif op == "service_response" and message.get("id") == "interop-drop-call":
            self.served = message.get("values")
            self.service_answered.set()
            return True
        return False

    async def on_report(self, run: CaseRun, update: Mapping[str, Any]) -> dict[str, Any]:
        if "registered" in update and self.dropped_at is None:
            await self._drop_and_wait(run, update["registered"])
        return {"reconnected": self.reconnected_at is not None}

    async def _drop_and_wait(self, run: CaseRun, said: Any) -> None:
        """Drop the first connection once what the driver registered is on the wire, then play the reconnection."""
        wanted = {str(item) for item in said} if isinstance(said, list) else set()
        # the registrations travel on another connection than the report: wait until they are in
        async with self.changed:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(
                    self.changed.wait_for(lambda: bool(self.registered.get(1)) and wanted <= self.registered[1]), 3.0
                )
        first = self.peers.get(1)
        if first is None:
            return
        self.dropped_at = run.elapsed()
        first.drop()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self.reconnected.wait(), self.RECONNECT_WINDOW)
            await asyncio.wait_for(self.restored.wait(), self.RESTORE_WINDOW)
        again = self.peers.get(2)
        if again is None:
            return
        done = self.registered.get(2, set())
        if f"subscribe {self.TOPIC}" in done:
            await again.send({"op": "publish", "topic": self.TOPIC, "msg": {"data": "after-reconnect"}})
        if f"advertise_service {self.SERVICE}" in done:
            call = {"op": "call_service", "id": "interop-drop-call", "service": self.SERVICE, "args": {}}
            await again.send(call)
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.service_answered.wait(), 3.0)

    def judge(self, run: CaseRun) -> tuple[Outcome, str]:
        if run.started is None:
            return Outcome.FAILED, "the client never connected to this case"
        before = sorted(self.registered.get(1, set()))
        if self.dropped_at is None:
            return Outcome.FAILED, f"the driver never said it had registered (seen: {before})"
        if self.reconnected_at is None:
            return (
                Outcome.UNIMPLEMENTED,
                f"the client did not reconnect within {self.RECONNECT_WINDOW:.0f} s of the drop",
            )
        after = self.registered.get(2, set())
        lost = [item for item in before if item not in after]
        took = f"reconnected {self.reconnected_at - self.dropped_at:.1f} s after the drop"
        if lost:
            return Outcome.FAILED, f"{took} but did not send again: {', '.join(lost)}"
        if (missing := no_report(run)) is not None:
            return missing[0], f"{took}; {missing[1]}"
        if "after-reconnect" not in (run.observed.get("received") or []):
            return Outcome.FAILED, f"{took}, subscribed again, but the program did not get the message sent after"
        if f"advertise_service {self.SERVICE}" in before and not self.service_answered.is_set():
            return Outcome.FAILED, f"{took}; the re-advertised service did not answer"
        return Outcome.OK, f"{took}; sent again: {', '.join(before)}; the message after it reached the program"


class SlowAnswer(Scenario):
    case = "clients.5"
    title = "A slow answer: the call times out, the late answer is harmless"
    statements = ("P-SRV-4", "P-CLI-5")
    expected = "a call with a 0.5 s timeout fails as timed out; after the late answer, a new call gets its own answer"
    SERVICE = "/interop/slow"
    HOLD = 6.0  # the longest the slow call is held when the driver never says it timed out
    time_limit = 12.0

    def __init__(self) -> None:
        self.held: list[tuple[Peer, Mapping[str, Any]]] = []
        self.carried_timeout: Any = None

    async def on_message(self, run: CaseRun, peer: Peer, message: Mapping[str, Any]) -> bool:
        if message.get("op") != "call_service" or message.get("service") != self.SERVICE:
            return False
        self.carried_timeout = message.get("timeout")
        self.held.append((peer, message))
        if run.observed.get("timeout_offered") is False:
            await self._answer_held()
        else:
            asyncio.get_running_loop().create_task(self._answer_at_last())
        return True

    async def _answer_at_last(self) -> None:
        await asyncio.sleep(self.HOLD)  # the server's patience, not a synchronisation: the case ends anyway
        await self._answer_held()

    async def _answer_held(self) -> None:
        held, self.held = self.held, []
        for peer, message in held:
            await peer.send(answer(message, {"data": "late"}))

    async def on_report(self, run: CaseRun, update: Mapping[str, Any]) -> dict[str, Any]:
        if "slow_call" in update:
            await self._answer_held()
        return {}

    def judge(self, run: CaseRun) -> tuple[Outcome, str]:
        if (missing := no_report(run)) is not None:
            return missing
        passed = f" (the call carried timeout {self.carried_timeout!r})" if self.carried_timeout is not None else ""
        if run.observed.get("timeout_offered") is False:
            return (
                Outcome.UNIMPLEMENTED,
                f"the client offers no call timeout; the call got {short(run.observed.get('slow_call'))}",
            )
        slow, after = run.observed.get("slow_call"), run.observed.get("after_late")
        if str(slow).startswith("no answer") and self.carried_timeout is not None:
            return Outcome.UNIMPLEMENTED, (
                f"the client has no timeout of its own: it sends timeout {self.carried_timeout!r} to the server"
                " and waits as long as the server takes"
            )
        if slow != "timed out":
            return Outcome.FAILED, f"the call with a 0.5 s timeout ended with {short(slow)}{passed}"
        if after != "after-late":
            return Outcome.FAILED, f"timed out, but after the late answer a new call got {short(after)}{passed}"
        return Outcome.OK, f"timed out; after the late answer a new call got its own answer{passed}"


class RefusedAuth(Scenario):
    case = "clients.6"
    title = "A refused login"
    statements = ("P-AUTH-1", "P-AUTH-3", "P-CLI-6")
    expected = "the program is told that the login was refused, and the client stops using the refused login"
    REASON = "authentication failed: wrong mac"
    RETRY_WINDOW = 3.0  # how long after the refusal a second login is waited for

    def __init__(self) -> None:
        self.attempts = 0
        self.before_auth: list[str] = []
        self.retried = asyncio.Event()

    async def on_message(self, run: CaseRun, peer: Peer, message: Mapping[str, Any]) -> bool:
        op = str(message.get("op"))
        if op != "auth":
            if self.attempts == 0:
                self.before_auth.append(op)
            return op == "call_service"  # refused with the connection: nothing is served before a login
        self.attempts += 1
        if self.attempts > 1:
            self.retried.set()
        status = {"op": "status", "level": "error", "msg": self.REASON}
        if "id" in message:
            status["id"] = message["id"]
        await peer.send(status)
        await peer.close(1008, self.REASON)
        return True

    async def on_report(self, run: CaseRun, update: Mapping[str, Any]) -> dict[str, Any]:
        """Before the driver closes its client, see whether the client tries the refused login again."""
        if update.get("done") and self.attempts == 1:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.retried.wait(), self.RETRY_WINDOW)
        return {"retried": self.retried.is_set()}

    def judge(self, run: CaseRun) -> tuple[Outcome, str]:
        if run.observed.get("auth_offered") is False:
            return Outcome.UNIMPLEMENTED, "the client has no way to send an auth message"
        if (missing := no_report(run)) is not None:
            return missing
        if self.attempts == 0:
            return Outcome.FAILED, f"the client sent no auth message (sent: {self.before_auth or 'nothing'})"
        refusal, closed = run.observed.get("refusal"), run.observed.get("closed")
        retried = f"; it sent the refused login again ({self.attempts} logins)" if self.attempts > 1 else ""
        early = f"; before its auth it sent {', '.join(self.before_auth)}" if self.before_auth else ""
        if refusal:
            outcome = Outcome.NON_STRICT if self.attempts > 1 else Outcome.OK
            return outcome, f"the program was told: {short(refusal, 200)}{retried}{early}"
        if run.observed.get("connected"):
            retried += "; afterwards the client is connected again, without a login"
        if closed:
            return Outcome.NON_STRICT, f"the program saw only a closed connection, not the refusal{retried}{early}"
        return Outcome.FAILED, f"the program was told nothing; it takes the client as connected{retried}{early}"


CASES: tuple[type[Scenario], ...] = (OutOfOrder, Fragmented, Status, Dropped, SlowAnswer, RefusedAuth)


def scenarios() -> list[Scenario]:
    """A fresh scenario of every case (each keeps the state of one run)."""
    return [case() for case in CASES]
