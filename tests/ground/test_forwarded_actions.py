"""Forwarding an operator action to the run's host through the database: answered once, or never performed.

Real databases (a SQLite file, the session's PostgreSQL as the runner role), real change feeds;
the host's performer is the test's, to count what it was asked.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from ground.action_requests import ActionRequests, Answer, ForwardedAction
from ground.change_feed import ChangeNotice, open_change_feed
from records.audit_log import AuditLog
from records.console_tables import run_action_requests
from support.web_server import GroundDatabase, new_ground_database


@pytest.fixture(params=["sqlite", "postgresql"])
def database(request: pytest.FixtureRequest, tmp_path: Path) -> GroundDatabase:
    postgres = request.getfixturevalue("postgres") if request.param == "postgresql" else None
    return new_ground_database(request.param, tmp_path, postgres)


@pytest.fixture
def audit(database: GroundDatabase) -> Iterator[AuditLog]:
    log = AuditLog(database.url)
    yield log
    log.close()


def requests_of(audit: AuditLog, host_id: str, performed: list[ForwardedAction]) -> ActionRequests:
    def perform(request: ForwardedAction) -> Answer:
        performed.append(request)
        return Answer(200, {"ok": True, "result": f"{request.action['action']} by {request.user}"})

    return ActionRequests(audit.engine, host_id=host_id, console=f"console {host_id}", perform=perform)


def test_a_request_is_performed_once_by_its_host_and_answered_to_the_asker(audit: AuditLog) -> None:
    performed: list[ForwardedAction] = []
    host, asker = requests_of(audit, "host-a", performed), requests_of(audit, "host-b", [])
    feed = open_change_feed(audit.engine)
    for side in (host, asker):
        feed.subscribe(side.notice)
    try:
        assert feed.connected.wait(10)
        answer = asker.forward("run-1", "host-a", "bob", {"action": "pause"})
        assert answer == Answer(200, {"ok": True, "result": "pause by bob"})
        assert [(r.run_id, r.user, r.console, r.action) for r in performed] == [
            ("run-1", "bob", "console host-b", {"action": "pause"})
        ]
    finally:
        feed.close()
        host.close()
        asker.close()


def test_a_request_nobody_takes_is_withdrawn_and_never_performed_later(audit: AuditLog) -> None:
    asker = requests_of(audit, "host-b", [])
    feed = open_change_feed(audit.engine)
    feed.subscribe(asker.notice)
    late: list[ForwardedAction] = []
    try:
        answer = asker.forward("run-1", "host-gone", "bob", {"action": "stop"}, take_within=0.5)
        assert answer.status == 504 and "not performed" in answer.body["error"]
        with audit.engine.connect() as connection:
            assert connection.execute(run_action_requests.select()).one().state == "expired"
        host = requests_of(audit, "host-gone", late)  # the host is back: it looks for what is pending
        host.notice(ChangeNotice("resync", ""))
        host.close()  # its worker finishes that look first
        assert late == []
    finally:
        feed.close()
        asker.close()


def test_a_host_that_was_away_performs_what_was_asked_meanwhile(audit: AuditLog) -> None:
    asker = requests_of(audit, "host-b", [])
    feed = open_change_feed(audit.engine)
    asked = threading.Event()
    feed.subscribe(asker.notice)
    feed.subscribe(lambda notice: asked.set() if notice.payload.startswith("pending ") else None)
    answers: list[Answer] = []

    def ask() -> None:
        answers.append(asker.forward("run-1", "host-a", "bob", {"action": "continue"}))

    asking = threading.Thread(target=ask)
    performed: list[ForwardedAction] = []
    try:
        assert feed.connected.wait(10)
        asking.start()
        assert asked.wait(10)  # the request is in the database, its host not listening
        host = requests_of(audit, "host-a", performed)
        host.notice(ChangeNotice("resync", ""))  # what its change feed says when it (re)connects
        asking.join(30)
        host.close()
        assert answers == [Answer(200, {"ok": True, "result": "continue by bob"})] and len(performed) == 1
    finally:
        feed.close()
        asker.close()
