"""Three habitats, two supervisors on one PostgreSQL ground database, one supervisor killed mid-run.

Three emulated habitats (support/emulated_habitat.py: real ``caretaker bridge`` and ``caretaker
onboard`` processes, the IVA procedure at the recorded robot's pace, each behind its own
``caretaker link`` delay) and two real ``caretaker supervise`` processes, each serving all three
bindings, as supervisors on two ground hosts sharing one database do. Each habitat gets an IVA
run handed through the real ``caretaker run --onboard --via-supervisor``. Once a run of the
supervisor that holds the most has its first command's result in the ground database, that
supervisor is SIGKILLed: the other takes its runs over when their leases run out, every run
completes, and every ground chain ends equal to its habitat's, hash for hash, no event twice.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from caretaker.processes import ManagedProcess
from ground.change_feed import ChangeNotice, open_change_feed
from pride.approvals import APPROVER_PASSWORD_ENV
from records.audit_chain import verify_chain
from records.audit_log import AuditLog
from records.onboard_handoffs import OnboardHandoffs
from support.emulated_habitat import EmulatedHabitat, fleet, kill_the_busier, supervise
from support.postgres import PostgresServer
from support.recorded_run import command_durations, recorded_events
from support.web_server import PEOPLE, new_ground_database

from .flight_support import RUN_TIMEOUT_S, result_of

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=70), pytest.mark.timeout(1200)]

#: One-way delays of the three habitats' links (s): each its own.
DELAYS = (0.1, 0.3, 0.6)


class GroundNotices:
    """What the ground database's change notices said: events stored (``<seq> <kind> <run>``) and
    handoffs' states (``<state> <run>``), as (channel, kind or state, run)."""

    def __init__(self) -> None:
        self._seen: set[tuple[str, str, str]] = set()
        self._changed = threading.Condition()

    def notice(self, change: ChangeNotice) -> None:  # the feed's thread
        words = change.payload.split()
        if change.channel in ("events", "handoffs") and len(words) >= 2:
            with self._changed:
                self._seen.add((change.channel, words[-2], words[-1]))
                self._changed.notify_all()

    def wait_for(self, channel: str, what: str, runs: list[str], *, every: bool, timeout: float) -> None:
        """Until ``what`` was said of any (``every``: each) of ``runs`` on ``channel``."""
        check = all if every else any
        with self._changed:
            assert self._changed.wait_for(lambda: check((channel, what, r) in self._seen for r in runs), timeout), (
                channel,
                what,
                runs,
            )


@pytest.fixture
def ground_db(postgres: PostgresServer, tmp_path: Path) -> str:
    """A new ground database on the session's PostgreSQL, as the runners and supervisors reach it."""
    return new_ground_database("postgresql", tmp_path, postgres).url


@pytest.fixture
def habitats(ros_env: dict[str, str], tmp_path: Path) -> Iterator[list[EmulatedHabitat]]:
    with fleet(tmp_path, ros_env, DELAYS) as started:
        yield started


def test_a_killed_supervisors_runs_are_taken_over_and_every_ground_chain_ends_equal_to_its_habitats(
    ground_db: str, habitats: list[EmulatedHabitat], ros_env: dict[str, str], tmp_path: Path
) -> None:
    # bob approves the unlock (second_operator.py); a supervisor killed leaves its scratch files in tmp_path
    env = {**ros_env, APPROVER_PASSWORD_ENV: PEOPLE["bob"][2], "TMPDIR": str(tmp_path)}
    audit = AuditLog(ground_db)
    handoffs = OnboardHandoffs(audit.engine)
    notices = GroundNotices()
    feed = open_change_feed(audit.engine)
    feed.subscribe(notices.notice)
    supervisors: list[tuple[ManagedProcess, str]] = []
    runners: list[ManagedProcess] = []
    try:
        assert feed.connected.wait(30)
        for n in (1, 2):
            supervisors.append(supervise(ground_db, habitats, env, f"supervise-{n}"))
        named = {name: process for process, name in supervisors}
        runners += [h.hand_run(ground_db, env) for h in habitats]
        run_ids = [runner.wait_for_line(r"^READY run ", 180).split()[-1] for runner in runners]
        # mid-run: a command's result of one of its runs has reached the ground
        takeover = kill_the_busier(  # two of three runs, or all three
            supervisors,
            run_ids,
            handoffs,
            lambda runs: notices.wait_for("events", "command_result", runs, every=False, timeout=RUN_TIMEOUT_S),
            within=120,
        )
        survivor, held = takeover.survivor, takeover.held[takeover.victim]
        notices.wait_for("handoffs", "ended", run_ids, every=True, timeout=RUN_TIMEOUT_S)
        for run_id in run_ids:
            handoff = handoffs.get(run_id)
            assert handoff is not None and (handoff.state, handoff.result, handoff.supervisor) == (
                "ended",
                "completed",
                survivor,
            ), (handoff, named[survivor].tail(40))
        for h, run_id, runner in zip(habitats, run_ids, runners, strict=True):
            ground, habitat = audit.stored_events(run_id), h.onboard_chain(run_id)
            assert ground and [(e.seq, e.kind, e.hash) for e in ground] == [(e.seq, e.kind, e.hash) for e in habitat]
            assert len({e.seq for e in ground}) == len(ground)  # no event stored twice
            assert verify_chain(run_id, ground).ok, verify_chain(run_id, ground).describe()
            assert habitat[-1].kind == "run_completed"
            # at the recorded robot's pace: each motion at least as long as the real arm's (a sleep is never shorter)
            motions, recorded = (
                command_durations(e)["execute_plan"] for e in (audit.events(run_id), recorded_events())
            )
            assert len(motions) == len(recorded) and all(m >= r for m, r in zip(motions, recorded, strict=True))
            # a runner whose supervisor died says the run goes on without it, unless it saw the takeover first
            ended = {"detached", "completed"} if run_id in held else {"completed"}
            assert result_of(runner)[1] in ended, runner.tail()
    finally:
        for process in runners + [process for process, _ in supervisors]:
            process.stop()
        feed.close()
        audit.close()
