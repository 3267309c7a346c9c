"""A ground that re-attaches: the supervising runner stops mid-run, the run goes on on the habitat,
and ``caretaker run --attach`` follows it again from another process.

The first runner is stopped (SIGTERM) at the run's first motion (the simulation at half speed, so
the rest of the run outlasts both attaches). The habitat never waits for the ground,
so the run goes on; ``caretaker run --attach RUN`` gets the unit the run started from from the
habitat, catches the ground's record up from the last event the first runner stored, hash for
hash, hosts the run for the consoles again and follows it to its end. A second ``--attach`` while
the first holds the run is refused and told who holds it.
"""

from __future__ import annotations

import os
import signal

import pytest

from caretaker.processes import VENV_BIN
from records.audit_chain import verify_chain

from .flight_support import DELAY, assert_flown_exactly_once, flight, result_of

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=90), pytest.mark.timeout(900)]


def test_a_run_whose_supervisor_stopped_is_followed_again_by_attach_and_a_second_attach_is_refused(
    ros_env: dict[str, str],
) -> None:
    with flight(ros_env, delay=DELAY, time_scale="0.5", onboard=True) as f:
        first = f.run("--onboard")
        run_id = first.wait_for_line(r"^READY run ", 120).split()[2]
        f.await_execution(r"\S+")  # the first motion
        os.kill(first.proc.pid, signal.SIGTERM)  # supervision ends; the run does not
        assert result_of(first, 120) == (run_id, "detached")
        assert first.proc.wait(60) != 0
        stored = len(f.ground_chain(run_id))

        attach = ["run", "--attach", run_id, "--binding", str(f.binding), "--db", f.db_url]
        attached = f.hosts.caretaker(f.hosts.ground, *attach, "--user", "flight-2", ready=r"^READY run ", timeout=240)
        assert attached.wait_for_line(r"^attached to onboard run ", 10).endswith(f"catching up from event {stored + 1}")
        second = f.hosts.run(
            f.hosts.ground, [str(VENV_BIN / "caretaker"), *attach, "--user", "flight-3"], timeout=240, check=False
        )
        said = f"second:\n{second.stdout}{second.stderr}\nfirst:\n{attached.tail()}"
        assert second.returncode == 2 and "--attach refused" in second.stderr, said
        assert f"run {run_id} is live on" in second.stderr, second.stderr  # who holds it

        _, status = result_of(attached)
        assert_flown_exactly_once(f, run_id, status)
        ground, habitat = f.ground_chain(run_id), f.habitat.onboard_chain(run_id)
        assert len(ground) > stored  # caught up, and followed on
        assert [(e.seq, e.kind, e.hash) for e in ground] == [(e.seq, e.kind, e.hash) for e in habitat]
        assert verify_chain(run_id, ground).ok, verify_chain(run_id, ground).describe()
