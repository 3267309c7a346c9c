"""Several requests following an onboard run at once (``/caretaker_onboard/follow``, onboard/followers.py):
each event goes down once, and the newest request waiting stays for the run's end.

The lab bench's habitat (tests/onboard/test_habitat_runs.py's fixtures); the ground's side, which
keeps such requests going across the link: tests/onboard/test_follow_requests.py.
"""

from __future__ import annotations

import queue
import threading
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from onboard.followers import Followers
from onboard.habitat_runs import EventsAnswer, HabitatRuns
from onboard.unit import OperatorAction, Unit
from procedure_language.sysrep import SysRep
from records.audit_chain import StoredEvent
from support.lab_gateway import LabGateway

from .test_habitat_runs import SECRET, act, habitat, make_unit, sysreps, uplink

__all__ = ["habitat", "make_unit", "sysreps"]  # the fixtures, used here by name


def _following(runs: HabitatRuns, run_id: str, answers: queue.Queue[EventsAnswer], wait_s: float) -> None:
    """A request to follow ``run_id`` on a thread of its own, as the bridge hands each request one."""
    threading.Thread(target=lambda: answers.put(runs.follow(run_id, 0, wait_s)), daemon=True).start()


def test_two_requests_waiting_share_the_events_and_the_newest_waits_for_the_runs_end(
    habitat: tuple[HabitatRuns, list[Any]], make_unit: Any
) -> None:
    runs, _ = habitat
    unit: Unit = make_unit(values={})  # it holds at the record 1.2 until the ground enters it
    assert uplink(runs, unit).state == "ACCEPTED"
    while not any(e["kind"] == "awaiting_operator" for e in runs.events(unit.run_id, 0, wait_s=5).events):
        pass
    answers: queue.Queue[EventsAnswer] = queue.Queue()
    _following(runs, unit.run_id, answers, wait_s=20)
    _following(runs, unit.run_id, answers, wait_s=20)
    first = answers.get(timeout=10)  # the older one answers once a newer one waits behind it
    assert first.status == "active" and [e["seq"] for e in first.events] == list(range(1, first.head_seq + 1))
    enter = {"value": "dock", "instruction": "1.2"}
    assert act(runs, OperatorAction("key-1", unit.run_id, "enter", "bob", time.time() + 60, enter)).state == "DONE"
    last = answers.get(timeout=10)  # the newest held what came after, until the run ended
    assert last.status == "completed" and last.events[-1]["kind"] == "run_completed"
    after = [e["seq"] for e in last.events]
    assert len(after) > 1 and after == list(range(first.head_seq + 1, last.head_seq + 1))  # each event once
    # every event is still there for a request to /events: the ground's catch-up after a lost answer
    everything = runs.events(unit.run_id, 0)
    assert [e["seq"] for e in everything.events] == list(range(1, last.head_seq + 1))
    again = runs.follow(unit.run_id, 0, wait_s=20)  # the run is over: answered at once, nothing sent twice
    assert (again.status, again.events, again.head_seq) == ("completed", [], last.head_seq)


def test_a_request_alone_with_news_answers_when_its_wait_is_over(
    habitat: tuple[HabitatRuns, list[Any]], make_unit: Any
) -> None:
    runs, _ = habitat
    unit: Unit = make_unit(values={})
    assert uplink(runs, unit).state == "ACCEPTED"
    while not any(e["kind"] == "awaiting_operator" for e in runs.events(unit.run_id, 0, wait_s=5).events):
        pass
    alone = runs.follow(unit.run_id, 0, wait_s=0.5)  # nobody came behind it: what it held goes down
    assert alone.status == "active" and [e["seq"] for e in alone.events] == list(range(1, alone.head_seq + 1))
    quiet = runs.follow(unit.run_id, 0, wait_s=0.5)  # nothing new since: an empty answer at the end of its wait
    assert (quiet.events, quiet.head_seq) == ([], alone.head_seq)


def test_a_request_for_events_while_a_unit_starts_waits_for_its_run_and_not_for_the_start(
    tmp_path: Path, sysreps: dict[str, SysRep], make_unit: Any
) -> None:
    """Starting a unit takes the habitat's lock for as long as its JVM starts (minutes on a loaded
    habitat); requests for the run's events meanwhile must wait as for a run, each for its own
    wait, not pile up behind the start holding request threads a Halt needs."""
    binding = tmp_path / "lab.yaml"
    binding.write_text("robot: lab\n")
    starting, started = threading.Event(), threading.Event()

    def slow_to_start(path: str, url: str | None) -> LabGateway:
        starting.set()  # the uplink holds the habitat's lock from here until the run started
        assert started.wait(20), "the test never let the gateway start"
        return LabGateway()

    runs = HabitatRuns(
        tmp_path / "habitat",
        secret=SECRET,
        bindings={"lab.yaml": binding},
        sysreps=sysreps,
        gateway_factory=slow_to_start,
    )
    try:
        unit: Unit = make_unit()
        uplinked: queue.Queue[Any] = queue.Queue()
        threading.Thread(target=lambda: uplinked.put(uplink(runs, unit)), daemon=True).start()
        assert starting.wait(20)
        during = runs.follow(unit.run_id, 0, wait_s=0.3)  # answered when its wait is over, the start still going
        assert (during.status, during.events) == ("active", [])
        started.set()
        assert uplinked.get(timeout=20).state == "ACCEPTED"
        assert runs.follow(unit.run_id, 0, wait_s=5).events[0]["kind"] == "run_started"
    finally:
        started.set()
        runs.close()


def test_what_is_new_goes_to_the_oldest_request_waiting_whichever_thread_asks_first() -> None:
    """Under load the habitat may run a newer request's thread before an older one's: the run's end
    must still go down in answer to the request that was there when it happened."""
    wakes: list[None] = []
    followers = Followers(lambda: wakes.append(None))
    now = datetime.now(UTC)
    stored = [
        StoredEvent("r", seq, now, "pax", "run_completed" if seq == 3 else "step", None, "{}", "") for seq in (1, 2, 3)
    ]

    def read(after: int) -> list[StoredEvent]:
        return [e for e in stored if e.seq > after]

    with followers.waiting("r", 0) as older:
        with followers.waiting("r", 0) as newer:
            assert followers.take(newer, read, ended=True, due=False, limit=10) is None
            taken = followers.take(older, read, ended=True, due=False, limit=10)
            assert taken is not None and [e.seq for e in taken[0]] == [1, 2, 3]
        woken = len(wakes)
    assert woken == 3  # two came, and the newer one's leaving wakes whoever waits behind
    with followers.waiting("r", 0) as last:  # what the older carried does not go down again
        assert followers.take(last, read, ended=True, due=False, limit=10) == ([], 3)
