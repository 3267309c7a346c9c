"""``caretaker supervise`` keeps the habitat's session open across the 1.3 s link; IVA runs are handed to it.

On the ground host the supervisor opens its session to the habitat once; the runners after it
(``caretaker run --onboard --via-supervisor``) build their units and hand them over through the
ground database instead of connecting. The supervisor uplinks each on its open session and
follows it to the end: the whole IVA procedure, then its first step again (the world is changed
by then), each completed with the ground's record the habitat's chain hash for hash, and the link
carried one connection in all, the supervisor's. A third run holds at a breakpoint, waiting for
an operator at the consoles, when its supervisor is stopped (SIGTERM): the run stays on the
habitat, its runner says so, and ``caretaker run --attach`` takes it over (with nobody at its
terminal it stops the run at the hold) with the record caught up. How a flight is set up:
flight_support.py.
"""

from __future__ import annotations

import os
import signal

import pytest

from records.audit_chain import verify_chain
from records.audit_log import AuditLog
from records.onboard_handoffs import OnboardHandoffs

from .flight_support import DELAY, Flight, flight, result_of

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=130), pytest.mark.timeout(1500)]


def _ground_is_habitat(f: Flight, run_id: str) -> None:
    """The run completed, and the ground's record of it is the habitat's chain."""
    ground, habitat = f.ground_chain(run_id), f.habitat.onboard_chain(run_id)
    assert ground and [(e.seq, e.kind, e.hash) for e in ground] == [(e.seq, e.kind, e.hash) for e in habitat]
    assert verify_chain(run_id, ground).ok, verify_chain(run_id, ground).describe()
    assert habitat[-1].kind == "run_completed"


def test_a_supervisor_keeps_its_session_and_supervises_the_runs_handed_to_it(ros_env: dict[str, str]) -> None:
    with flight(ros_env, delay=DELAY, time_scale="0", onboard=True) as f:
        supervise = ("supervise", "--binding", str(f.binding), "--db", f.db_url)
        supervisor = f.hosts.caretaker(f.hosts.ground, *supervise, ready=r"^READY supervise ", timeout=180)
        assert len(f.link.control.stats().connections) == 1  # its session, open before any run
        for part in ((), ("--to", "prepare")):
            run = f.run("--onboard", "--via-supervisor", *part)
            run_id, status = result_of(run)
            assert status == "completed", run.tail(40)
            _ground_is_habitat(f, run_id)
            assert f"{run_id}: ENDED completed" in supervisor.tail(400)
        connections = f.link.control.stats().connections
        assert len(connections) == 1 and connections[0].closed is None, connections  # no handshake per run

        # Supervision stops while a run holds on the habitat: the run stays there, and an attach takes it over.
        run = f.run("--onboard", "--via-supervisor", "--to", "prepare", "--break", "1.3", "--at-consoles")
        run_id = run.wait_for_line(r"^READY run ", 120).split()[-1]
        supervisor.wait_for_line(rf"^{run_id}: the onboard run waits for an operator: 1\.3", 120)
        os.kill(supervisor.proc.pid, signal.SIGTERM)
        supervisor.wait_for_line(r"^supervision stopped: the runs go on on the habitat", 120)
        assert result_of(run) == (run_id, "detached") and f"caretaker run --attach {run_id}" in run.tail(5)
        audit = AuditLog(f.db_url)
        try:
            handoff = OnboardHandoffs(audit.engine).get(run_id)
        finally:
            audit.close()
        assert handoff is not None and handoff.state == "detached", handoff
        assert f.habitat.onboard_chain(run_id)[-1].kind == "breakpoint_hit"  # the run holds there still
        attach = ("run", "--attach", run_id, "--binding", str(f.binding), "--db", f.db_url, "--user", "flight")
        attached = f.hosts.caretaker(f.hosts.ground, *attach, ready=r"^READY run ", timeout=180)
        assert result_of(attached) == (run_id, "stopped"), attached.tail(40)  # nobody at its terminal for the hold
        ground, habitat = f.ground_chain(run_id), f.habitat.onboard_chain(run_id)
        assert [(e.seq, e.hash) for e in ground] == [(e.seq, e.hash) for e in habitat]
        assert habitat[-1].kind == "run_stopped"
