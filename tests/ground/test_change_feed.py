"""One watcher of the ground database per process (ground/change_feed.py): a supervisor hosting
fifty runs opens fifty feeds, and PostgreSQL must see one LISTEN connection, not fifty (each
would get every notice of every run, and the server's connection slots run out).

Real databases: a SQLite file and the session's PostgreSQL.
"""

from __future__ import annotations

import queue

import sqlalchemy as sa

from ground.change_feed import ChangeNotice, open_change_feed
from records.audit_log import AuditLog
from records.onboard_handoffs import OnboardHandoffs


def _listeners(audit: AuditLog) -> int:
    with audit.engine.connect() as connection:
        return int(
            connection.execute(
                sa.text(
                    "SELECT count(*) FROM pg_stat_activity WHERE application_name = 'caretaker-feed' "
                    "AND datname = current_database()"
                )
            ).scalar_one()
        )


def _handed(audit: AuditLog, run_id: str) -> None:
    """A change every feed announces: a run handed to a supervisor (PostgreSQL: its trigger
    NOTIFYs; SQLite: the poll reads it)."""
    OnboardHandoffs(audit.engine).hand(run_id, binding="b.yaml", unit_json="{}", user="bob", at_consoles=False)


def test_the_feeds_of_one_process_share_one_watcher_and_each_gets_every_notice_until_it_closes(
    audit: AuditLog,
) -> None:
    heard: list[queue.Queue[ChangeNotice]] = [queue.Queue() for _ in range(5)]
    feeds = [open_change_feed(audit.engine) for _ in heard]
    try:
        for feed, inbox in zip(feeds, heard, strict=True):
            feed.subscribe(inbox.put)
            assert feed.connected.wait(10)
        if audit.engine.dialect.name == "postgresql":
            assert _listeners(audit) == 1
        _handed(audit, "run-1")
        for inbox in heard:
            assert _next_handoff(inbox) == "handed run-1"
        feeds[0].close()
        _handed(audit, "run-2")
        for inbox in heard[1:]:  # the others still hear
            assert _next_handoff(inbox) == "handed run-2"
        assert all(n.channel != "handoffs" for n in _drained(heard[0]))  # the closed one no more
    finally:
        for feed in feeds:
            feed.close()
    if audit.engine.dialect.name == "postgresql":
        assert _listeners_gone(audit)


def _next_handoff(inbox: queue.Queue[ChangeNotice]) -> str:
    while True:
        notice = inbox.get(timeout=10)
        if notice.channel == "handoffs":
            return notice.payload


def _drained(inbox: queue.Queue[ChangeNotice]) -> list[ChangeNotice]:
    found = []
    while not inbox.empty():
        found.append(inbox.get_nowait())
    return found


def _listeners_gone(audit: AuditLog) -> bool:
    """The last feed closed: its watcher's connection ends (the server notes it at once)."""
    with audit.engine.connect() as connection:
        for _ in range(100):
            if not _listeners(audit):
                return True
            connection.execute(sa.text("SELECT pg_sleep(0.1)"))
    return False
