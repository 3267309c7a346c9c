"""The IVA procedure flown across the Gateway link, ground to habitat: a 30 s hold on a lossy link.

One scenario of the IVA procedure flown autonomously from the ground host to the habitat host
(1.3 s each way); how a flight is set up, and how what the arm did is counted on the habitat,
is flight_support.py's docstring. One file per scenario, so parallel workers fly them side by side.
The run is the procedure's steps 1 to 3 (``--to place_dirty``): the preparation the pull-out
needs (its templates, its looks and locates), the pull-out the hold falls in, and a motion
after the link is back; the steps after them would add round trips, not news of the link.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest

from pride.events import EventKind

from .flight_support import (
    DELAY,
    PLACE_DIRTY_STEP,
    PULL_OUT,
    assert_flown_exactly_once,
    assert_in_flight,
    flight,
    result_of,
)

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=240), pytest.mark.timeout(900)]

HOLD_S = 30.0


def test_a_30_s_hold_on_a_lossy_link_mid_motion_is_ridden_out(ros_env: dict[str, str]) -> None:
    """1.3 s one way with 5 % of segments lost; all traffic held for 30 s from the start of the
    pull-out. The motion itself is not what is tested here: the simulation runs as fast as it can."""
    with flight(ros_env, delay=DELAY, link_options=["--loss", "0.05", "--seed", "15"], time_scale="0") as f:
        run = f.run("--to", PLACE_DIRTY_STEP, record=False)
        f.await_execution(PULL_OUT)
        f.link.control.hold(HOLD_S)
        held_at = datetime.now(UTC)
        run_id, status = result_of(run)
        assert_flown_exactly_once(f, run_id, status, to=PLACE_DIRTY_STEP)
        events = f.events(run_id)
        assert_in_flight(events, PULL_OUT, held_at)
        # The held link stayed connected (its keepalive gives up after 128 s), yet the run said at
        # once that it had no news, with the pull-out in flight, while the link was still held.
        lost = [e for e in events if e.kind is EventKind.LINK_LOST]
        assert any(
            e.data.to_json()["quiet"]
            and e.data.to_json()["in_flight"] == 1
            and e.time < held_at + timedelta(seconds=HOLD_S)
            for e in lost
        ), [(e.time, e.data) for e in lost]
        assert EventKind.LINK_RESTORED in {e.kind for e in events}
        stats = f.link.control.stats()
        assert stats.holds == 1 and stats.up_stalls + stats.down_stalls > 0, stats
        assert not [c for c in stats.connections if c.ended_by == "reset by outage"]
