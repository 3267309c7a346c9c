"""The ground follows an onboard run with a request always waiting on the habitat (onboard/follow_requests.py):
it hears of the run's end from a request that was there when the end happened, never one sent after.

The habitat is the lab bench's (tests/onboard/test_habitat_runs.py's fixtures) behind a link
emulated in this process: each request and each answer takes the link's one-way delay, as through
the bridge and ``caretaker link`` (the IVA procedure across the real link: tests/flight).
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from onboard.downlink import OnboardSupervisor, Supervision
from onboard.habitat_runs import HabitatRuns
from onboard.onboard_server import events_values
from onboard.unit import EVENTS_SERVICE, FOLLOW_SERVICE, UPLINK_SERVICE, OperatorAction, Unit
from pride.events import Event, EventKind
from records.audit_log import AuditLog
from rosbridge_wire.client import Endpoint, LinkError, RosbridgeClient

from .test_habitat_runs import SECRET, act, habitat, make_unit, sysreps

__all__ = ["habitat", "make_unit", "sysreps"]  # the fixtures, used here by name

pytestmark = pytest.mark.timeout(60)

ONE_WAY_S = 0.4
_ACCEPTANCE_HELD_S = 20.0


@dataclass
class Crossing:
    """One request across the link: what it asked, when it reached the habitat and what it was answered."""

    service: str
    args: Mapping[str, Any]
    arrived: float  # the habitat's clock
    answer: dict[str, Any]


class LinkedHabitat(RosbridgeClient):
    """The habitat's onboard services ``ONE_WAY_S`` away, as the ground's session reaches them.
    ``lose(n)`` makes the n-th answer to a follow request with events lost on its way down."""

    def __init__(self, runs: HabitatRuns) -> None:
        super().__init__(Endpoint("wss://habitat.invalid", one_way_delay=ONE_WAY_S, secret=SECRET), name="lab-link")
        self.runs = runs
        self.crossings: list[Crossing] = []
        self.lost: set[int] = set()
        self.unit_held = asyncio.Event()  # cleared: the unit reaches the habitat after the first follow request
        self.unit_held.set()
        self.acceptance_after = 0  # the unit's answer reaches the ground once this many follow requests arrived
        self.follows_arrived = 0
        self.follows_before_acceptance = 0
        self._follow_came = asyncio.Event()
        self.opened.set()  # the session is open and answered: requests go out at once
        self.ready.set()

    async def _hold_acceptance(self) -> None:
        """Keep the unit's answer until ``acceptance_after`` follow requests arrived, or
        ``_ACCEPTANCE_HELD_S`` passed (a ground that waits for this answer before asking again
        would otherwise never get it); note how many had arrived when it went down."""
        deadline = time.monotonic() + _ACCEPTANCE_HELD_S
        while self.follows_arrived < self.acceptance_after and time.monotonic() < deadline:
            self._follow_came.clear()
            try:
                await asyncio.wait_for(self._follow_came.wait(), deadline - time.monotonic())
            except TimeoutError:
                break
        self.follows_before_acceptance = self.follows_arrived

    async def call(self, service: str, args: Mapping[str, Any], *, timeout: float | None = None) -> Mapping[str, Any]:
        handlers: dict[str, Callable[[], Any]] = {
            UPLINK_SERVICE: lambda: self.runs.uplink(str(args["unit_json"]), str(args["signature"])),
            EVENTS_SERVICE: lambda: events_values(self.runs.events, args),
            FOLLOW_SERVICE: lambda: events_values(self.runs.follow, args),
        }
        await asyncio.sleep(ONE_WAY_S)  # on its way up
        if service == UPLINK_SERVICE:
            await self.unit_held.wait()
        if service == FOLLOW_SERVICE:
            self.follows_arrived += 1
            self._follow_came.set()
        arrived = time.time()
        answer = dataclasses.asdict(await asyncio.to_thread(handlers[service]))
        if service == FOLLOW_SERVICE:
            self.unit_held.set()
        crossing = Crossing(service, args, arrived, answer)
        self.crossings.append(crossing)
        carried = [c for c in self.crossings if c.service == FOLLOW_SERVICE and c.answer["events_json"] != "[]"]
        await asyncio.sleep(ONE_WAY_S)  # and down
        if service == UPLINK_SERVICE:
            await self._hold_acceptance()
        if carried and carried[-1] is crossing and len(carried) in self.lost:
            raise LinkError(service, "the rosbridge connection was lost")
        return answer


def _supervised(
    runs: HabitatRuns, unit: Unit, tmp_path: Path, link: LinkedHabitat, *, holds: bool = True
) -> tuple[Supervision, list[str], AuditLog]:
    """Supervise ``unit`` from a ground across ``link``; the operator enters the record the run
    holds at (``holds``), on the habitat, once the ground has heard that it holds."""
    ground = AuditLog(f"sqlite:///{tmp_path / 'ground.db'}")
    said: list[str] = []

    async def supervise() -> Supervision:
        held = asyncio.Event()

        def on_event(event: Event) -> None:
            if event.kind is EventKind.AWAITING_OPERATOR:
                held.set()

        supervisor = OnboardSupervisor(
            link.endpoint, unit, ground, on_event=on_event, say=said.append, unattended=False, client=link
        )
        supervising = asyncio.create_task(supervisor.supervise())
        if not holds:
            return await supervising
        await held.wait()
        enter = {"value": "dock", "instruction": "1.2"}
        entered = OperatorAction("key-1", unit.run_id, "enter", "bob", time.time() + 60, enter)
        assert (await asyncio.to_thread(act, runs, entered)).state == "DONE"
        return await supervising

    return asyncio.run(supervise()), said, ground


def test_the_ground_hears_of_the_runs_end_from_a_request_waiting_there_when_it_ended(
    habitat: tuple[HabitatRuns, list[Any]], make_unit: Callable[..., Unit], tmp_path: Path
) -> None:
    runs, _ = habitat
    unit = make_unit(values={})  # it holds at the record 1.2 until the operator enters it
    link = LinkedHabitat(runs)
    result, said, ground = _supervised(runs, unit, tmp_path, link)
    try:
        assert result.status == "completed", said
        here, there = ground.stored_events(unit.run_id), runs.audit.stored_events(unit.run_id)
        assert [(e.seq, e.hash) for e in here] == [(e.seq, e.hash) for e in there]
        ended = next(e for e in there if e.kind == EventKind.RUN_COMPLETED.value).time.timestamp()
        follows = [c for c in link.crossings if c.service == FOLLOW_SERVICE]
        end = next(c for c in follows if '"run_completed"' in c.answer["events_json"])
        assert end.arrived < ended, "the end came down in answer to a request sent after it"
        uplink = next(c for c in link.crossings if c.service == UPLINK_SERVICE)
        assert uplink.arrived <= follows[0].arrived < end.arrived  # the first request right behind the unit
        # each event came down once: the requests waiting side by side shared them
        carried = [seq for c in follows for seq in _seqs(c.answer)]
        assert sorted(carried) == [e.seq for e in there]
        assert not [c for c in link.crossings if c.service == EVENTS_SERVICE]  # nothing was lost to catch up
    finally:
        ground.close()


def test_requests_keep_going_while_the_units_answer_is_on_its_way_down(
    habitat: tuple[HabitatRuns, list[Any]], make_unit: Callable[..., Unit], tmp_path: Path
) -> None:
    """A run shorter than the unit's round trip ends before the ground hears that it started: a
    request for its events must be there all the same, so none waits for the unit's answer."""
    runs, _ = habitat
    unit = make_unit()  # nothing to answer on the way: it runs to its end
    link = LinkedHabitat(runs)
    link.acceptance_after = 3  # the unit's answer comes down after three requests for events went up
    result, said, ground = _supervised(runs, unit, tmp_path, link, holds=False)
    try:
        assert result.status == "completed", said
        here, there = ground.stored_events(unit.run_id), runs.audit.stored_events(unit.run_id)
        assert [(e.seq, e.hash) for e in here] == [(e.seq, e.hash) for e in there]
        # the ground kept asking while the unit's answer was held: three requests were there before it came
        assert link.follows_before_acceptance >= 3
    finally:
        ground.close()


def test_a_request_that_reached_the_habitat_before_the_unit_did_is_not_taken_for_the_runs_end(
    habitat: tuple[HabitatRuns, list[Any]], make_unit: Callable[..., Unit], tmp_path: Path
) -> None:
    runs, _ = habitat
    unit = make_unit(values={})
    link = LinkedHabitat(runs)
    link.unit_held.clear()  # the first request for events overtakes the unit on the way up
    result, said, ground = _supervised(runs, unit, tmp_path, link)
    try:
        first = next(c for c in link.crossings if c.service == FOLLOW_SERVICE)
        assert first.answer["status"] == "unknown" and link.crossings.index(first) == 0
        assert result.status == "completed", said
        here, there = ground.stored_events(unit.run_id), runs.audit.stored_events(unit.run_id)
        assert [(e.seq, e.hash) for e in here] == [(e.seq, e.hash) for e in there]
    finally:
        ground.close()


def test_an_answer_lost_on_the_way_down_is_caught_up_from_the_habitats_chain(
    habitat: tuple[HabitatRuns, list[Any]], make_unit: Callable[..., Unit], tmp_path: Path
) -> None:
    runs, _ = habitat
    unit = make_unit(values={})
    link = LinkedHabitat(runs)
    link.lost = {1}  # the first answer with events never reaches the ground
    result, said, ground = _supervised(runs, unit, tmp_path, link)
    try:
        assert result.status == "completed", said
        here, there = ground.stored_events(unit.run_id), runs.audit.stored_events(unit.run_id)
        assert [(e.seq, e.hash) for e in here] == [(e.seq, e.hash) for e in there]
        catch_up = [c for c in link.crossings if c.service == EVENTS_SERVICE]
        assert catch_up and catch_up[0].args["wait_s"] == 0 and _seqs(catch_up[0].answer)[0] == 1
        gap = next(i for i, line in enumerate(said) if "no news from the habitat since" in line)
        assert any("the habitat answers again" in line for line in said[gap:]), said
    finally:
        ground.close()


def _seqs(answer: Mapping[str, Any]) -> list[int]:
    return [int(e["seq"]) for e in json.loads(answer["events_json"])]
