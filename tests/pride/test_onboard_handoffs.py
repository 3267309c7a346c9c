"""Onboard runs handed to a supervisor through the ground database (records/onboard_handoffs.py), on
SQLite and on PostgreSQL as the runner role: one supervisor takes a run, a runner's withdrawal and a
supervisor's take exclude each other, and every step is a change notice the waiting runner and the
supervisors hear (a NOTIFY on PostgreSQL, the change feed's reading of the file on SQLite).

The processes around it, flown across the emulated link: tests/flight/test_onboard_supervise.py.
"""

from __future__ import annotations

import queue

from ground.change_feed import ChangeNotice, open_change_feed
from records.audit_log import AuditLog
from records.onboard_handoffs import OnboardHandoffs
from support.audit import AuditDatabase


def test_a_handed_run_is_taken_by_one_supervisor_and_each_step_is_a_notice(database: AuditDatabase) -> None:
    log = AuditLog(database.url)
    heard: queue.Queue[ChangeNotice] = queue.Queue()
    feed = open_change_feed(log.engine)
    feed.subscribe(lambda notice: heard.put(notice) if notice.channel == "handoffs" else None)
    try:
        assert feed.connected.wait(10)
        handoffs = OnboardHandoffs(log.engine)

        def notice() -> str:
            return heard.get(timeout=10).payload

        handoffs.hand("run-1", binding="iva-ground.yaml", unit_json="{}", user="alice", at_consoles=True)
        assert notice() == "handed run-1"
        assert [h.run_id for h in handoffs.waiting("iva-ground.yaml")] == ["run-1"]
        assert handoffs.waiting("eva.yaml") == []  # a supervisor of another binding does not see it
        assert handoffs.take("run-1", "supervisor A")
        assert not handoffs.take("run-1", "supervisor B")  # taken already: one supervisor holds a run
        assert notice() == "taken run-1"
        assert not handoffs.withdraw("run-1")  # the runner waited too long, but a supervisor had taken it
        assert handoffs.uplinked("run-1") and notice() == "uplinked run-1"
        assert handoffs.end("run-1", detached=True, result="detached", message="supervision stopped", supervisor=None)
        assert notice() == "detached run-1"
        assert not handoffs.end("run-1", detached=False, result="completed", supervisor=None)  # its supervision is over
        detached = handoffs.get("run-1")
        assert detached is not None and (detached.state, detached.supervisor) == ("detached", "supervisor A")
        # it goes on on the habitat: another supervisor of the binding takes it over, one only
        assert [h.run_id for h in handoffs.supervised("iva-ground.yaml")] == ["run-1"]
        assert handoffs.take_over(detached, "supervisor B") and notice() == "uplinked run-1"
        assert not handoffs.take_over(detached, "supervisor C")  # B was first: A's run is no more
        assert not handoffs.end("run-1", detached=True, result="detached", supervisor="supervisor A")  # not A's now
        taken_over = handoffs.get("run-1")
        assert taken_over is not None and (taken_over.state, taken_over.supervisor) == ("uplinked", "supervisor B")
        assert handoffs.end("run-1", detached=False, result="completed", supervisor="supervisor B")
        assert notice() == "ended run-1" and handoffs.supervised("iva-ground.yaml") == []

        handoffs.hand("run-3", binding="iva-ground.yaml", unit_json="{}", user="bob", at_consoles=False)
        assert notice() == "handed run-3"
        assert handoffs.take("run-3", "supervisor B") and notice() == "taken run-3"
        assert handoffs.end("run-3", detached=False, result="refused", message="no binding lab.yaml", supervisor=None)
        assert notice() == "ended run-3"
        ended = handoffs.get("run-3")
        assert ended is not None and (ended.state, ended.result) == ("ended", "refused")
        assert (ended.supervisor, ended.message) == ("supervisor B", "no binding lab.yaml")

        handoffs.hand("run-2", binding="iva-ground.yaml", unit_json="{}", user="alice", at_consoles=False)
        assert notice() == "handed run-2"
        assert handoffs.withdraw("run-2") and notice() == "withdrawn run-2"
        assert not handoffs.take("run-2", "supervisor A")  # nobody takes a withdrawn run
        assert handoffs.waiting("iva-ground.yaml") == []
    finally:
        feed.close()
        log.close()
