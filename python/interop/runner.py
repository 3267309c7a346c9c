"""Cases and how they run: each is a small async function with a number, a title, a profile, the
statements it cites and a time limit; the runner turns whatever happens into a ``CaseResult``.

A timeout, a dropped connection or an exception inside a case becomes FAILED with what was seen,
never a traceback: the server under test is the one allowed to misbehave, not the suite.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import re
import ssl
import time
from collections.abc import Awaitable, Callable, Iterable
from dataclasses import dataclass

from .outcome import CaseResult, Outcome
from .session import ROSBRIDGE_OPS, Conversation, Credentials, NotAnswered
from .wire import Recorder, WebSocket, WireClosed

__all__ = ["Case", "CaseContext", "Deviation", "Target", "Verdict", "run_case", "run_cases"]

log = logging.getLogger(__name__)

_UNSUPPORTED = re.compile(r"unknown op|not supported|unsupported|not implemented", re.IGNORECASE)


@dataclass(frozen=True)
class Verdict:
    """What a case concluded: its outcome and, in words, what it observed."""

    outcome: Outcome
    observed: str


class Deviation(Exception):
    """Raised inside a case to end it at once with this verdict."""

    def __init__(self, outcome: Outcome, observed: str) -> None:
        super().__init__(observed)
        self.verdict = Verdict(outcome, observed)


@dataclass(frozen=True)
class Target:
    """The server under test and how to reach it."""

    url: str
    ssl_context: ssl.SSLContext | None = None
    credentials: Credentials | None = None
    one_way_delay: float = 0.0  # of a link between the suite and the server (seconds)
    outage: float = 0.0  # the longest the link may hold traffic (seconds)
    quiet: float = 30.0  # how long the link profile's quiet client reads nothing (seconds)

    @property
    def latency(self) -> float:
        """What a wait for anything on its way grows by: a round trip of the link."""
        return 2 * self.one_way_delay


class CaseContext:
    """What a case works with: connections to the target, its recorder, a name space of its own."""

    def __init__(self, target: Target, number: str, run_id: str, profile: str = "") -> None:
        self.target = target
        self.profile = profile
        self.recorder = Recorder()
        # ROS names may not hold dots or start a token with a digit: core.3 -> /interop_<run>/core_3
        self.prefix = f"/interop_{run_id}/{re.sub(r'[^A-Za-z0-9_]', '_', number)}"
        self._conversations: list[Conversation] = []
        self._sockets: list[WebSocket] = []

    async def window(self, seconds: float) -> None:
        """Wait ``seconds`` (plus the link's latency) for messages that may still be on their way."""
        await asyncio.sleep(seconds + self.target.latency)

    def name(self, leaf: str) -> str:
        """A ROS name no other case (nor another run) uses."""
        return f"{self.prefix}/{leaf}"

    async def connect(self, label: str = "A", *, authenticate: bool = True) -> Conversation:
        """A conversation with the target, closed when the case ends (authenticated if a secret is known)."""
        conversation = await Conversation.open(
            self.target.url,
            self.recorder,
            label,
            ssl_context=self.target.ssl_context,
            credentials=self.target.credentials if authenticate else None,
            latency=self.target.latency,
            outage=self.target.outage,
        )
        self._conversations.append(conversation)
        return conversation

    async def connect_pair(self, first: str, second: str) -> tuple[Conversation, Conversation]:
        """Two conversations opened at once (over a long link each opening costs round trips)."""
        one, two = await asyncio.gather(self.connect(first), self.connect(second))
        return one, two

    async def raw_socket(self, label: str = "raw") -> WebSocket:
        """A bare WebSocket (no auth, nothing read for the case): for the framing cases."""
        socket = await WebSocket.connect(self.target.url, self.recorder, label, ssl_context=self.target.ssl_context)
        self._sockets.append(socket)
        return socket

    def refused_as_unknown(self) -> str | None:
        """The status text with which the server refused an op of the protocol this case sent as
        unknown or unsupported (the case is then UNIMPLEMENTED, not FAILED), if it did."""
        ops = ROSBRIDGE_OPS if self.profile == "auth" else ROSBRIDGE_OPS - {"auth"}  # else only the preamble
        sent = {op for op in ops if any(f'"op": "{op}"' in f.text for f in self.recorder.frames)}
        for conversation in self._conversations:
            for message in conversation.received:
                text = str(message.get("msg", "")) if message.get("op") == "status" else ""
                if _UNSUPPORTED.search(text) and any(re.search(rf"\b{op}\b", text) for op in sent):
                    return text
        return None

    async def close_all(self) -> None:
        await asyncio.gather(*(c.close() for c in self._conversations), *(s.close() for s in self._sockets))


CaseFunction = Callable[[CaseContext], Awaitable[Verdict]]


@dataclass(frozen=True)
class Case:
    """One numbered case of the suite."""

    number: str  # "core.3"
    title: str
    profile: str
    statements: tuple[str, ...]
    expected: str
    timeout: float
    run: CaseFunction


async def run_case(case: Case, target: Target, run_id: str) -> CaseResult:
    """Run one case within its time; every way it can end is a ``CaseResult``."""
    context = CaseContext(target, case.number, run_id, case.profile)
    # a case makes a dozen round trips or so, and one outage may hold any of them
    limit = case.timeout + 20 * target.latency + 2 * target.outage
    started = time.monotonic()
    try:
        verdict = await asyncio.wait_for(case.run(context), limit)
    except Deviation as deviation:
        verdict = deviation.verdict
    except TimeoutError:
        verdict = Verdict(Outcome.FAILED, f"the case did not end within {limit:g} s")
    except NotAnswered as missing:
        verdict = Verdict(Outcome.FAILED, str(missing))
    except WireClosed as closed:
        verdict = Verdict(Outcome.FAILED, f"the server closed the connection (code {closed.code} {closed.reason})")
    except (OSError, ConnectionError) as error:
        verdict = Verdict(Outcome.FAILED, f"connection failed: {error}")
    except Exception as error:  # a case must never end the run: the server's answer may be anything
        log.debug("case %s raised", case.number, exc_info=True)
        verdict = Verdict(Outcome.FAILED, f"unexpected answer ({type(error).__name__}: {error})")
    finally:
        with contextlib.suppress(TimeoutError, OSError):
            await asyncio.wait_for(context.close_all(), 5)
    if verdict.outcome is not Outcome.OK:
        refusal = context.refused_as_unknown()
        if refusal is not None:
            verdict = Verdict(Outcome.UNIMPLEMENTED, f"{refusal!r} ({verdict.observed})")
    return CaseResult(
        case=case.number,
        title=case.title,
        statements=case.statements,
        outcome=verdict.outcome,
        expected=case.expected,
        observed=verdict.observed,
        duration=round(time.monotonic() - started, 3),
        frames=tuple(context.recorder.frames),
        extra={"profile": case.profile},
    )


#: Profiles whose cases run all at once, as the clients of a ground share one link: one by one,
#: round trips of a long link would make them take many minutes.
TOGETHER = ("link",)


async def run_cases(
    cases: Iterable[Case], target: Target, on_result: Callable[[CaseResult], None] | None = None
) -> list[CaseResult]:
    """Run cases one after another (each has the server to itself), those of the profiles in
    :data:`TOGETHER` all at once; ``on_result`` sees each as it ends. Results in the cases' order."""
    run_id = os.urandom(3).hex()
    ordered = list(cases)
    results: dict[str, CaseResult] = {}

    async def one(case: Case) -> None:
        result = await run_case(case, target, run_id)
        if on_result is not None:
            on_result(result)
        results[case.number] = result

    for case in ordered:
        if case.profile not in TOGETHER:
            await one(case)
    await asyncio.gather(*(one(case) for case in ordered if case.profile in TOGETHER))
    return [results[case.number] for case in ordered]
