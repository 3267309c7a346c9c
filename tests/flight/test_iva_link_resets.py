"""The IVA procedure flown across the Gateway link, ground to habitat: resets and a bridge crash mid-motion.

One scenario of the IVA procedure flown autonomously from the ground host to the habitat host
(1.3 s each way); how a flight is set up, and how what the arm did is counted on the habitat,
is flight_support.py's docstring. One file per scenario, so parallel workers fly them side by side.
"""

from __future__ import annotations

from datetime import UTC, datetime

import pytest

from .flight_support import DELAY, PLACE_DIRTY, PULL_OUT, assert_flown_exactly_once, assert_in_flight, flight, result_of

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=210), pytest.mark.timeout(900)]


def test_resets_and_a_bridge_crash_mid_motion_leave_every_motion_done_once(ros_env: dict[str, str]) -> None:
    """1.3 s one way; the connection reset for 10 s while the pull-out executes; the habitat's
    bridge killed (and restarted by ``caretaker up``) while the dirty filter is placed."""
    with flight(ros_env, delay=DELAY, time_scale="1") as f:
        run = f.run()
        f.await_execution(PULL_OUT)
        f.link.control.reset(10)
        reset_at = datetime.now(UTC)
        f.await_execution(PLACE_DIRTY)
        killed = f.kill_part("bridge")
        killed_at = datetime.now(UTC)
        restarted = f.habitat.up.wait_for_line(r"^restarted bridge", 120)
        run_id, status = result_of(run)
        assert_flown_exactly_once(f, run_id, status)
        assert_in_flight(f.events(run_id), PULL_OUT, reset_at)
        assert_in_flight(f.events(run_id), PLACE_DIRTY, killed_at)
        stats = f.link.control.stats()
        assert stats.resets == 1 and stats.refused >= 1, stats
        reset = [c for c in stats.connections if c.ended_by == "reset by outage"]
        assert reset, "the ground's connection was cut by the reset"
        assert "bridge died" in f.habitat.up.tail(400) and restarted, f"bridge {killed} not restarted"
