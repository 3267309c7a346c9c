"""The onboard executive killed while the pull-out it commanded is in flight, restarted by ``caretaker up``.

It resumes the run from its own chain: the command in flight at the crash is sent again with its
key, so the ledger answers what became of it instead of running it again. The run completes,
every command was executed once and every motion done once (counted on the habitat), and the
ground's copy of the record, caught up after the gap, is the habitat's chain hash for hash.
The run is the procedure's steps 1 to 3 (``--to place_dirty``): what the pull-out needs, the
pull-out, and a motion the resumed executive commands after it; the simulation flat out but for
the pull-out, paced at real time, so that the kill falls mid-motion. How a flight is set up:
flight_support.py.
"""

from __future__ import annotations

import pytest

from records.audit_chain import verify_chain

from .flight_support import DELAY, PLACE_DIRTY_STEP, PROCEDURE, PULL_OUT, arm_goals, flight, nominal_commands, result_of

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=90), pytest.mark.timeout(900)]


def test_the_onboard_executive_killed_mid_motion_resumes_and_runs_nothing_twice(ros_env: dict[str, str]) -> None:
    with flight(ros_env, delay=DELAY, time_scale="0", paced={PULL_OUT: 1.0}, onboard=True) as f:
        run = f.run("--onboard", "--to", PLACE_DIRTY_STEP, record=False)
        f.await_execution(PULL_OUT)
        killed = f.kill_part("onboard")
        f.habitat.up.wait_for_line(r"^restarted onboard", 120)
        run_id, status = result_of(run)
        habitat = f.habitat.onboard_chain(run_id)
        assert status == "completed", [f"{e.seq} {e.kind} {e.data[:120]}" for e in habitat[-10:]]
        resumed = [e for e in habitat if e.kind == "run_resumed"]
        assert [e.actor for e in resumed] == ["onboard"], f"onboard executive {killed} was not resumed once"
        records = f.habitat.ledger_records()  # each command key executed at most once, whatever was re-sent
        assert len(records) == len(nominal_commands(PROCEDURE, to=PLACE_DIRTY_STEP)), records
        assert {r["state"] for r in records} == {"SUCCEEDED"}, records
        goals = f.goals()
        assert len({goal for goal, _ in goals}) == len(goals) == arm_goals(PLACE_DIRTY_STEP), goals
        assert {s for _, s in goals} == {4}, goals
        ground = f.ground_chain(run_id)
        assert [(e.seq, e.hash) for e in ground] == [(e.seq, e.hash) for e in habitat]
        assert verify_chain(run_id, ground).ok
        # The ground's follower says so when a poll of the events fails, and again when the habitat
        # answers. A restart quick enough for the bridge to hand the next poll to the new executive
        # leaves no gap to say (once, in a fresh clone); a gap it said must be one it closed.
        said = run.tail(400)
        gap = said.find("no news from the habitat since")
        assert gap < 0 or "the habitat answers again" in said[gap:], said
        print(
            "the ground saw a gap and caught up" if gap >= 0 else "the ground's polls never failed across the restart"
        )
