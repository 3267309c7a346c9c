"""The IVA procedure run onboard: the habitat runs it, the ground supervises across 1.3 s each way.

``caretaker run --onboard`` on the ground host uplinks the procedure as a signed unit through the
emulated link to the habitat's onboard executive (a part of its ``caretaker up``), which runs it
next to the robot; the ground follows the run's events and stores them. The run completes, the
arm did every motion once (counted on the habitat), and the ground's audit log is the habitat's
chain event for event, hash for hash.
"""

from __future__ import annotations

import pytest

from records.audit_chain import verify_chain

from .flight_support import DELAY, assert_flown_exactly_once, flight, result_of

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=60), pytest.mark.timeout(900)]


def test_the_iva_procedure_flown_onboard_completes_and_the_ground_keeps_the_habitats_chain(
    ros_env: dict[str, str],
) -> None:
    # time scale 0: the motions as fast as the simulation goes (bench/link.py times them at 1)
    with flight(ros_env, delay=DELAY, time_scale="0", onboard=True) as f:
        run = f.run("--onboard")
        unit = run.wait_for_line(r"^uplinked unit [0-9a-f]{64}", 120).split()[2]
        run_id, status = result_of(run)
        assert_flown_exactly_once(f, run_id, status)
        ground, habitat = f.ground_chain(run_id), f.habitat.onboard_chain(run_id)
        assert [(e.seq, e.kind, e.hash) for e in ground] == [(e.seq, e.kind, e.hash) for e in habitat]
        assert verify_chain(run_id, ground).ok, verify_chain(run_id, ground).describe()
        started, ended = ground[0].time, ground[-1].time
        print(f"onboard run {run_id} (unit {unit[:12]}): {(ended - started).total_seconds():.1f} s on the habitat")
