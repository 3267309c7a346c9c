"""An onboard run through an outage: all traffic held for 60 s from the start of the pull-out.

The habitat finishes the IVA procedure alone while the link is held (every motion once, counted on
the habitat); the ground says since when it has no news, then catches up, and its audit log is
the habitat's chain, hash for hash. How a flight is set up: flight_support.py.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest

from pride.audit_chain import utc

from .flight_support import DELAY, PULL_OUT, assert_flown_exactly_once, flight, result_of

pytestmark = [pytest.mark.ros, pytest.mark.slow]


#: Longer than the ground client's keepalive gives up (its connection is dropped and made again)
#: and than the rest of the onboard run: the habitat finishes alone, the ground catches up afterwards.
OUTAGE_S = 60.0


def test_an_outage_from_the_pull_out_on_the_habitat_finishes_alone_and_the_ground_catches_up(
    ros_env: dict[str, str],
) -> None:
    with flight(ros_env, delay=DELAY, time_scale="0", onboard=True) as f:  # the motions at full speed
        run = f.run("--onboard")
        f.await_execution(PULL_OUT)
        f.link.control.hold(OUTAGE_S)
        held_at = datetime.now(UTC)
        silent = run.wait_for_line(r"no news from the habitat since", 120)
        run_id, status = result_of(run)
        caught_up = run.wait_for_line(r"the habitat answers again; catching up from event \d+", 5)
        habitat = f.habitat.onboard_chain(run_id)
        ended = habitat[-1]
        # every motion and the end of the run happened on the habitat while the link was held
        assert ended.kind == "run_completed" and utc(ended.time) < held_at + timedelta(seconds=OUTAGE_S), (
            f"the habitat ended at {ended.time}, the outage from {held_at} lasted {OUTAGE_S} s"
        )
        assert_flown_exactly_once(f, run_id, status)
        ground = f.ground_chain(run_id)
        assert [(e.seq, e.hash) for e in ground] == [(e.seq, e.hash) for e in habitat], "caught up, not the same"
        assert f.link.control.stats().holds == 1
        print(f"{silent.strip()} / {caught_up.strip()}")
