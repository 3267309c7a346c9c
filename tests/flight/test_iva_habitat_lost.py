"""The IVA procedure flown across the Gateway link, ground to habitat: the habitat lost mid-motion.

One scenario of the IVA procedure flown autonomously from the ground host to the habitat host
(1.3 s each way); how a flight is set up, and how what the arm did is counted on the habitat,
is flight_support.py's docstring. One file per scenario, so parallel workers fly them side by side.
The simulation runs flat out but for the pull-out, which it carries out at real pace, so that the
habitat dies mid-motion.
"""

from __future__ import annotations

import pytest

from pride.events import EventKind

from .flight_support import DELAY, PULL_OUT, commands, flight

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=115), pytest.mark.timeout(900)]


def test_an_outcome_lost_with_the_habitat_is_unknown_and_holds(ros_env: dict[str, str]) -> None:
    """The whole habitat side dies during the pull-out and comes back with its memory lost (a new
    ledger epoch): what became of the pull-out cannot be learnt. The run says so and holds for an
    operator; it never logs the pull-out as a success (nor as a failure)."""
    with flight(ros_env, delay=DELAY, time_scale="0", paced={PULL_OUT: 1.0}, outage_budget=120) as f:
        run = f.run()
        f.await_execution(PULL_OUT)
        f.habitat.up.kill()
        f.restart_habitat_without_memory()
        held = run.wait_for_line(r"outcome unknown|unknown outcome", 300)
        run_id = run.wait_for_line(r"^READY run ").split()[2]
        events = f.events(run_id)
        pull = next(
            s
            for s, _ in commands(events)
            if s.data.to_json()["command"] == "execute_plan" and s.data.to_json()["args"]["trajectory"] == PULL_OUT
        )
        answers = [e for e in events if e.kind is EventKind.COMMAND_RESULT and e.instruction == pull.instruction]
        assert answers and all(
            a.data.to_json()["outcome"] == "unknown" and a.data.to_json()["success"] is None for a in answers
        ), held
        assert not [
            e
            for e in events
            if e.kind in (EventKind.INSTRUCTION_COMPLETED, EventKind.INSTRUCTION_FAILED)
            and e.instruction == pull.instruction
        ]
        # held for an operator, saying why; the pull-out's answer may be recorded again after the
        # hold (unknown again: asserted above), as a fresh clone's run once read it
        holds = [e for e in events if e.kind is EventKind.AWAITING_OPERATOR]
        assert holds and "unknown" in holds[-1].data.to_json()["reason"], holds
        after = events[events.index(holds[-1]) + 1 :]
        assert all(e in answers for e in after), [(e.seq, e.kind.value, e.data) for e in after]
        assert run.running, "it holds: no RESULT"
