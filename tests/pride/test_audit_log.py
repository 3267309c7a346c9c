"""The audit log: append-only records per run, in order, in UTC, never two with one sequence number."""

from __future__ import annotations

from datetime import timezone

import pytest
from sqlalchemy.exc import IntegrityError

from pride.audit_log import AuditLog
from pride.events import PAX, Event, EventKind


def test_records_come_back_in_order_with_their_data_and_utc_times(tmp_path) -> None:
    log = AuditLog(f"sqlite:///{tmp_path / 'nested' / 'audit.db'}")
    log.append(Event("run-a", 1, EventKind.RUN_STARTED, "alice", None, {"procedure": "p", "steps": [{"number": 1}]}))
    log.append(Event("run-b", 1, EventKind.RUN_STARTED, "bob", None, {"procedure": "q"}))
    log.append(Event("run-a", 2, EventKind.COMMAND_SENT, PAX, "1.1", {"args": {"speed": 0.5, "ok": True}}))
    events = log.events("run-a")
    assert [(e.seq, e.kind, e.actor, e.instruction) for e in events] == [
        (1, EventKind.RUN_STARTED, "alice", None), (2, EventKind.COMMAND_SENT, PAX, "1.1")]
    assert events[1].data == {"args": {"speed": 0.5, "ok": True}}
    assert all(e.time.tzinfo is not None and e.time.utcoffset() == timezone.utc.utcoffset(None) for e in events)
    assert [(run, proc) for run, _, proc in log.runs()] == [("run-a", "p"), ("run-b", "q")]
    log.close()


def test_a_sequence_number_is_never_written_twice(tmp_path) -> None:
    log = AuditLog(f"sqlite:///{tmp_path / 'audit.db'}")
    log.append(Event("run-a", 1, EventKind.RUN_STARTED, "alice"))
    with pytest.raises(IntegrityError):
        log.append(Event("run-a", 1, EventKind.PAUSED, "mallory"))
    assert [e.kind for e in log.events("run-a")] == [EventKind.RUN_STARTED]
    log.close()


def test_records_survive_a_new_connection(tmp_path) -> None:
    url = f"sqlite:///{tmp_path / 'audit.db'}"
    first = AuditLog(url)
    first.append(Event("run-a", 1, EventKind.RUN_STARTED, "alice"))
    first.close()
    assert [e.actor for e in AuditLog(url).events("run-a")] == ["alice"]
