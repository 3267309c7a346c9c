"""The IVA procedure flown across the Gateway link, ground to habitat: resets and a bridge crash mid-motion.

One scenario of the IVA procedure flown autonomously from the ground host to the habitat host
(1.3 s each way); how a flight is set up, and how what the arm did is counted on the habitat,
is flight_support.py's docstring. One file per scenario, so parallel workers fly them side by side.
The run is the procedure's steps 1 to 3 (``--to place_dirty``): the preparation the pull-out
needs (its templates, its looks and locates), the pull-out the reset falls in and the placement
the crash falls in; the steps after them would add round trips, not news of the link. The
simulation runs flat out but for those two motions, which it carries out at real pace, so that
the faults struck at their starts fall mid-motion.
"""

from __future__ import annotations

from datetime import UTC, datetime

import pytest

from .flight_support import (
    DELAY,
    PLACE_DIRTY,
    PLACE_DIRTY_STEP,
    PULL_OUT,
    assert_flown_exactly_once,
    assert_in_flight,
    flight,
    result_of,
)

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=210), pytest.mark.timeout(900)]


def test_resets_and_a_bridge_crash_mid_motion_leave_every_motion_done_once(ros_env: dict[str, str]) -> None:
    """1.3 s one way; the connection reset for 10 s while the pull-out executes; the habitat's
    bridge killed (and restarted by ``caretaker up``) while the dirty filter is placed."""
    with flight(ros_env, delay=DELAY, time_scale="0", paced={PULL_OUT: 1.0, PLACE_DIRTY: 1.0}) as f:
        run = f.run("--to", PLACE_DIRTY_STEP, record=False)
        f.await_execution(PULL_OUT)
        f.link.control.reset(10)
        reset_at = datetime.now(UTC)
        f.await_execution(PLACE_DIRTY)
        killed = f.kill_part("bridge")
        killed_at = datetime.now(UTC)
        restarted = f.habitat.up.wait_for_line(r"^restarted bridge", 120)
        run_id, status = result_of(run)
        assert_flown_exactly_once(f, run_id, status, to=PLACE_DIRTY_STEP)
        assert_in_flight(f.events(run_id), PULL_OUT, reset_at)
        assert_in_flight(f.events(run_id), PLACE_DIRTY, killed_at)
        stats = f.link.control.stats()
        assert stats.resets == 1 and stats.refused >= 1, stats
        reset = [c for c in stats.connections if c.ended_by == "reset by outage"]
        assert reset, "the ground's connection was cut by the reset"
        assert "bridge died" in f.habitat.up.tail(400) and restarted, f"bridge {killed} not restarted"
