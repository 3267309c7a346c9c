"""A unit handed to the supervisors of its binding (ground/handed_run.py), as a console's start on
the habitat and ``caretaker run --onboard --via-supervisor`` hand it: the handoff followed through
the change feed while a supervisor, played here by another thread's conditional updates, takes it,
or does not.

Real databases: a SQLite file and the session's PostgreSQL. The real supervisor and habitat:
tests/onboard/test_handed_runs.py and tests/web/test_fleet_view.py.
"""

from __future__ import annotations

import threading

from ground.handed_run import HandedRun
from records.audit_log import AuditLog
from records.onboard_handoffs import OnboardHandoffs


def _handed(audit: AuditLog, run_id: str) -> HandedRun:
    handed = HandedRun(audit, run_id)
    handed.hand(binding="b.yaml", unit_json="{}", user="alice", at_consoles=True)
    return handed


def test_a_unit_no_supervisor_takes_is_withdrawn_and_nothing_goes_up(audit: AuditLog) -> None:
    handed = _handed(audit, "run-1")
    try:
        assert handed.taken(0.3) is None
    finally:
        handed.close()
    handoffs = OnboardHandoffs(audit.engine)
    found = handoffs.get("run-1")
    assert found is not None and found.state == "withdrawn"
    assert not handoffs.take("run-1", "late supervisor")  # a supervisor that finds it later leaves it


def test_a_handed_unit_is_ready_once_its_supervisor_says_the_habitat_took_it(audit: AuditLog) -> None:
    handoffs = OnboardHandoffs(audit.engine)
    handed = _handed(audit, "run-2")
    supervised = threading.Event()

    def supervisor() -> None:  # takes it, then hears the habitat accepted the unit
        assert handoffs.take("run-2", "ground-1")
        supervised.wait(30)  # until the handing side waits for the habitat
        assert handoffs.uplinked("run-2")

    thread = threading.Thread(target=supervisor)
    thread.start()
    try:
        taken = handed.taken(30)
        assert taken is not None and (taken.state, taken.supervisor) == ("taken", "ground-1")
        supervised.set()
        handoff, ready = handed.ready(30)
        assert ready and handoff.state == "uplinked"
    finally:
        thread.join()
        handed.close()


def test_a_unit_the_habitat_refused_is_not_ready_and_the_handoff_says_why(audit: AuditLog) -> None:
    handoffs = OnboardHandoffs(audit.engine)
    handed = _handed(audit, "run-3")
    try:
        assert handoffs.take("run-3", "ground-1")
        assert handoffs.end("run-3", detached=False, result="refused", message="unit expired", supervisor="ground-1")
        handoff, ready = handed.ready(30)
    finally:
        handed.close()
    assert not ready and (handoff.state, handoff.message) == ("ended", "unit expired")
