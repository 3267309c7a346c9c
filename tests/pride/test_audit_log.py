"""The audit log on SQLite and PostgreSQL: append-only records per run, in order, in UTC, in a hash
chain that shows any edit; grants and triggers that refuse edits; logs from before migrations
upgraded in place."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from collections.abc import Callable
from dataclasses import replace
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path
from typing import Any, Self

import psycopg
import pytest
from psycopg.abc import Params, Query
from sqlalchemy import Column, DateTime, Integer, MetaData, String, Table, Text, UniqueConstraint, create_engine, event
from sqlalchemy.exc import DBAPIError, IntegrityError
from sqlalchemy.pool import ConnectionPoolEntry

from pride.events import PAX, Event, EventKind
from records.audit_chain import GENESIS
from records.audit_log import AuditLog, AuditSequenceError, database_url
from records.audit_schema import AuditSchemaError, _config, _revisions, head_revision
from support.audit import AuditDatabase
from support.postgres import OWNER, RUNNER, PostgresServer
from support.processes import COMMAND_HANG_S


def caretaker(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "caretaker.cli", *args], capture_output=True, text=True, timeout=COMMAND_HANG_S
    )


def test_records_come_back_in_order_with_their_data_and_utc_times(database: AuditDatabase) -> None:
    log = AuditLog(database.url)
    log.append(Event("run-a", 1, EventKind.RUN_STARTED, "alice", None, {"procedure": "p", "steps": [{"number": 1}]}))
    log.append(Event("run-b", 1, EventKind.RUN_STARTED, "bob", None, {"procedure": "q"}))
    log.append(
        Event(
            "run-a",
            2,
            EventKind.COMMAND_SENT,
            PAX,
            "1.1",
            {"args": {"speed": 0.5, "ok": True}},
            datetime(2030, 1, 2, 3, 4, 5, 678901, tzinfo=timezone(timedelta(hours=2))),
        )
    )
    events = log.events("run-a")
    assert [(e.seq, e.kind, e.actor, e.instruction) for e in events] == [
        (1, EventKind.RUN_STARTED, "alice", None),
        (2, EventKind.COMMAND_SENT, PAX, "1.1"),
    ]
    assert events[1].data.to_json() == {"args": {"speed": 0.5, "ok": True}}
    assert events[1].time == datetime(2030, 1, 2, 1, 4, 5, 678901, tzinfo=UTC)
    assert all(e.time.utcoffset() == timedelta(0) for e in events)
    assert [(run, proc) for run, _, proc in log.runs()] == [("run-a", "p"), ("run-b", "q")]
    log.close()


def test_an_appended_event_is_committed_when_append_returns(database: AuditDatabase) -> None:
    log = AuditLog(database.url)
    for seq in (1, 2, 3):
        log.append(Event("run-a", seq, EventKind.RUN_STARTED if seq == 1 else EventKind.PAUSED, "alice"))
        seen = (
            database.server.sql("SELECT count(*) FROM audit_records", database=database.name)
            if database.server is not None
            else sqlite3.connect(database.url.removeprefix("sqlite:///"))
            .execute("SELECT count(*) FROM audit_records")
            .fetchall()
        )
        assert seen == [(seq,)]  # another connection, another process could read it: it is durable
    log.close()


def _append_through_one_failure(log: AuditLog) -> list[bool]:
    """Append events 1 and 2 to run-a; the fault the caller installed strikes during event 2."""
    states: list[bool] = []
    log.add_availability_listener(lambda state: states.append(state.available))
    log.append(Event("run-a", 1, EventKind.RUN_STARTED, "alice"))
    return states


def test_an_append_whose_answer_was_lost_is_stored_once(postgres: PostgresServer, audit_template: str) -> None:
    """The connection drops right after the INSERT ran and committed (autocommit): the retry must find
    its row rather than fail on it, and never store it twice."""
    log = AuditLog(postgres.url(postgres.new_database(template=audit_template), RUNNER))
    states = _append_through_one_failure(log)
    lost: list[str] = []

    class AnswerLost(psycopg.Cursor):  # type: ignore[type-arg]
        def execute(self, query: Query, params: Params | None = None, **kwargs: Any) -> Self:
            done = super().execute(query, params, **kwargs)
            if str(query).startswith("INSERT") and not lost:
                lost.append(str(query))
                raise psycopg.OperationalError("server closed the connection unexpectedly")
            return done

    # on every connection given out from now (not by disposing of the pool: the announcer of event
    # 1 may hold a connection then, which a disposed pool would leave unclosed to the collector)
    event.listen(
        log._engine,
        "checkout",
        lambda dbapi_connection, _record, _proxy: setattr(dbapi_connection, "cursor_factory", AnswerLost),
    )
    log.append(Event("run-a", 2, EventKind.PAUSED, "alice"))
    assert lost and states == [False, True]
    assert [e.seq for e in log.events("run-a")] == [1, 2] and log.verify("run-a").ok
    log.close()


def test_an_interrupted_sqlite_append_is_retried(tmp_path: Path) -> None:
    log = AuditLog(f"sqlite:///{tmp_path / 'audit.db'}")
    states = _append_through_one_failure(log)
    interrupted: list[bool] = []

    def first_statement_only() -> bool:  # a true answer makes sqlite3 raise OperationalError('interrupted')
        if interrupted:
            return False
        interrupted.append(True)
        return True

    def interrupt_once(dbapi_connection: sqlite3.Connection, _record: ConnectionPoolEntry) -> None:
        dbapi_connection.set_progress_handler(first_statement_only, 1)

    log._engine.dispose()
    event.listen(log._engine, "connect", interrupt_once)
    log.append(Event("run-a", 2, EventKind.PAUSED, "alice"))
    assert interrupted and states == [False, True]
    assert [e.seq for e in log.events("run-a")] == [1, 2] and log.verify("run-a").ok
    log.close()


def test_a_sqlite_log_is_created_with_its_folder(tmp_path: Path) -> None:
    log = AuditLog(f"sqlite:///{tmp_path / 'nested' / 'audit.db'}")
    log.append(Event("run-a", 1, EventKind.RUN_STARTED, "alice"))
    assert (tmp_path / "nested" / "audit.db").is_file() and log.verify("run-a").ok
    log.close()


def test_a_sequence_number_is_never_written_twice_nor_skipped(database: AuditDatabase) -> None:
    log = AuditLog(database.url)
    log.append(Event("run-a", 1, EventKind.RUN_STARTED, "alice"))
    with pytest.raises(AuditSequenceError, match="event 1 is not the next event \\(expected 2\\)"):
        log.append(Event("run-a", 1, EventKind.PAUSED, "mallory"))
    with pytest.raises(AuditSequenceError, match="expected 2"):
        log.append(Event("run-a", 3, EventKind.PAUSED, "mallory"))
    other = AuditLog(database.url)  # a second writer of the same run: the database has the last word
    other.append(Event("run-a", 2, EventKind.PAUSED, "bob"))
    with pytest.raises(IntegrityError):
        log.append(Event("run-a", 2, EventKind.PAUSED, "mallory"))
    assert [e.actor for e in log.events("run-a")] == ["alice", "bob"]
    assert log.verify("run-a").ok
    log.close()
    other.close()


def test_events_appended_together_are_stored_all_in_one_transaction_or_none(database: AuditDatabase) -> None:
    """A downlinked answer's events go in with one commit: all of them, chained, or none at all."""
    log = AuditLog(database.url)
    log.append_all([Event("run-a", seq, EventKind.PAUSED, "hab") for seq in (1, 2, 3)])
    assert [e.seq for e in log.events("run-a")] == [1, 2, 3] and log.verify("run-a").ok
    database.tamper(  # event 5 is there already: the batch of 4 and 5 fails on its second event
        "INSERT INTO audit_records (run_id, seq, time, actor, kind, instruction, data, prev_hash, hash) "
        "VALUES ('run-a', 5, '2030-01-01 00:00:00', 'mallory', 'paused', NULL, '{}', 'x', 'y')"
    )
    with pytest.raises(IntegrityError):
        log.append_all([Event("run-a", 4, EventKind.PAUSED, "hab"), Event("run-a", 5, EventKind.PAUSED, "hab")])
    assert [(e.seq, e.actor) for e in log.events("run-a")] == [(1, "hab"), (2, "hab"), (3, "hab"), (5, "mallory")]
    with pytest.raises(AuditSequenceError, match="event 6 is not the next event \\(expected 5\\)"):
        log.append_all([Event("run-a", 4, EventKind.PAUSED, "hab"), Event("run-a", 6, EventKind.PAUSED, "hab")])
    with pytest.raises(ValueError, match="one run"):
        log.append_all([Event("run-b", 1, EventKind.RUN_STARTED, "hab"), Event("run-a", 4, EventKind.PAUSED, "hab")])
    assert [e.seq for e in log.events("run-a")] == [1, 2, 3, 5] and log.events("run-b") == []
    log.close()


def test_records_survive_a_new_connection_and_the_chain_goes_on(database: AuditDatabase) -> None:
    first = AuditLog(database.url)
    first.append(Event("run-a", 1, EventKind.RUN_STARTED, "alice"))
    first.close()
    second = AuditLog(database.url)  # a resuming runner: it learns the run's last hash from the database
    second.append(Event("run-a", 2, EventKind.RUN_RESUMED, "bob"))
    assert [e.actor for e in second.events("run-a")] == ["alice", "bob"]
    assert second.verify("run-a").ok
    second.close()


def test_every_event_links_to_the_previous_one_of_its_run(database: AuditDatabase) -> None:
    log = AuditLog(database.url)
    for seq in (1, 2, 3):
        log.append(Event("run-a", seq, EventKind.RUN_STARTED if seq == 1 else EventKind.PAUSED, "alice"))
        log.append(Event("run-b", seq, EventKind.RUN_STARTED if seq == 1 else EventKind.CONTINUED, "bob"))
    stored = log.stored_events("run-a")
    assert stored[0].prev_hash == GENESIS
    assert [s.prev_hash for s in stored[1:]] == [s.hash for s in stored[:-1]]
    assert all(s.hash == s.expected_hash() for s in stored)
    check = log.verify("run-a")
    assert check.ok and check.events == 3 and check.head == stored[-1].hash
    assert log.verify("run-b").head != check.head
    assert not log.verify("run-none").ok and log.verify("run-none").describe() == "run run-none: no events"
    log.close()


def test_nobody_updates_or_deletes_events_and_the_runner_is_refused_by_its_grants(database: AuditDatabase) -> None:
    log = AuditLog(database.url)
    log.append(Event("run-a", 1, EventKind.RUN_STARTED, "alice"))
    log.close()
    if database.server is None:  # SQLite has no roles: triggers refuse whoever opens the file
        with sqlite3.connect(database.url.removeprefix("sqlite:///")) as connection:
            for statement in ("UPDATE audit_records SET actor = 'mallory'", "DELETE FROM audit_records"):
                with pytest.raises(sqlite3.IntegrityError, match="audit records are append-only"):
                    connection.execute(statement)
    else:
        for statement in (
            "UPDATE audit_records SET actor = 'mallory'",
            "DELETE FROM audit_records",
            "TRUNCATE audit_records",
        ):
            with pytest.raises(Exception, match="permission denied for table audit_records"):
                database.server.sql(statement, database=database.name, role=RUNNER)
            with pytest.raises(Exception, match="audit records are append-only"):  # not even its owner
                database.server.sql(statement, database=database.name, role=OWNER)
    log = AuditLog(database.url)
    try:
        assert [e.actor for e in log.events("run-a")] == ["alice"]
    finally:
        log.close()  # an engine left to the garbage collector warns later, in whichever test runs then


@pytest.mark.parametrize(
    "tamper, problem",
    [
        (
            "UPDATE audit_records SET actor = 'mallory' WHERE run_id = 'run-a' AND seq = 3",
            "event 3 (command_sent at 1.1) was changed after it was written",
        ),
        (
            "UPDATE audit_records SET actor = 'mallory', hash = '{hash}' WHERE run_id = 'run-a' AND seq = 3",
            "event 4 (command_result at 1.1) does not link to event 3: that event was replaced or its hash rewritten",
        ),
        (
            "DELETE FROM audit_records WHERE run_id = 'run-a' AND seq = 2",
            "event 3 (command_sent at 1.1) follows a gap: event 2 removed",
        ),
    ],
)
def test_an_edit_made_bypassing_the_protections_is_named_by_verify(
    database: AuditDatabase, tamper: str, problem: str
) -> None:
    log = AuditLog(database.url)
    kinds = [
        EventKind.RUN_STARTED,
        EventKind.INSTRUCTION_STARTED,
        EventKind.COMMAND_SENT,
        EventKind.COMMAND_RESULT,
        EventKind.RUN_COMPLETED,
    ]
    for seq, kind in enumerate(kinds, start=1):
        log.append(Event("run-a", seq, kind, PAX, None if seq in (1, 5) else "1.1", {"procedure": "p"}))
    log.append(Event("run-b", 1, EventKind.RUN_STARTED, "bob", None, {"procedure": "p"}))
    intact = caretaker("report", "run-a", "--verify", "--db", database.url)
    assert intact.returncode == 0 and "run run-a: chain of 5 events intact" in intact.stdout, intact.stderr

    stored = log.stored_events("run-a")[2]  # a forger who recomputes event 3's own hash after editing it
    forged = replace(stored, actor="mallory").expected_hash()
    database.tamper(tamper.format(hash=forged))
    broken = caretaker("report", "run-a", "--verify", "--db", database.url)
    assert broken.returncode == 1
    assert problem in broken.stderr, broken.stderr
    assert caretaker("report", "run-b", "--verify", "--db", database.url).returncode == 0  # other runs unaffected
    log.close()


def _todays_log(url: str) -> None:
    """An audit log exactly as the code before migrations wrote it: its table shape, its rows."""
    metadata = MetaData()
    table = Table(
        "audit_records",
        metadata,
        Column("id", Integer, primary_key=True, autoincrement=True),
        Column("run_id", String(120), nullable=False, index=True),
        Column("seq", Integer, nullable=False),
        Column("time", DateTime(timezone=True), nullable=False),
        Column("actor", String(120), nullable=False),
        Column("kind", String(40), nullable=False),
        Column("instruction", String(80), nullable=True),
        Column("data", Text, nullable=False),
        UniqueConstraint("run_id", "seq", name="one_record_per_seq"),
    )
    engine = create_engine(database_url(url))
    metadata.create_all(engine)
    start = datetime(2026, 3, 4, 5, 6, 7, 123456, tzinfo=UTC)
    rows = [
        {
            "run_id": run,
            "seq": seq,
            "time": start + timedelta(seconds=seq),
            "actor": "alice",
            "kind": kind,
            "instruction": None if seq == 1 else "1.1",
            "data": data,
        }
        for run in ("old-1", "old-2")
        for seq, kind, data in (
            (1, "run_started", '{"procedure": "lab_all_kinds"}'),
            (2, "command_sent", '{"args": {"target": "dock"}, "command": "move"}'),
            (3, "run_stopped", '{"reason": "end of shift"}'),
        )
    ]
    with engine.begin() as connection:
        connection.execute(table.insert(), rows)
    engine.dispose()


def test_a_log_from_before_migrations_is_upgraded_in_place(new_database: Callable[..., AuditDatabase]) -> None:
    database: AuditDatabase = new_database(empty=True)
    _todays_log(database.owner_url)
    log = AuditLog(database.owner_url)
    assert log.schema_revision() == head_revision()
    assert [(run, proc) for run, _, proc in log.runs()] == [("old-1", "lab_all_kinds"), ("old-2", "lab_all_kinds")]
    events = log.events("old-1")
    assert [(e.seq, e.kind, e.data.to_json().get("command")) for e in events] == [
        (1, EventKind.RUN_STARTED, None),
        (2, EventKind.COMMAND_SENT, "move"),
        (3, EventKind.RUN_STOPPED, None),
    ]
    assert events[0].time == datetime(2026, 3, 4, 5, 6, 8, 123456, tzinfo=UTC)
    assert log.verify("old-1").ok and log.verify("old-2").ok
    log.append(Event("old-1", 4, EventKind.RUN_RESUMED, "bob"))  # the old run goes on, in the same chain
    assert log.verify("old-1").ok and log.verify("old-1").events == 4
    log.close()
    with pytest.raises(DBAPIError, match="append-only"):
        engine = create_engine(database_url(database.owner_url))
        with engine.begin() as connection:
            connection.exec_driver_sql("DELETE FROM audit_records")
    engine.dispose()


def test_a_log_written_by_a_newer_caretaker_is_refused(database: AuditDatabase) -> None:
    engine = create_engine(database_url(database.owner_url))
    with engine.begin() as connection:
        connection.exec_driver_sql("UPDATE audit_schema_version SET version_num = '9999'")
    engine.dispose()
    with pytest.raises(AuditSchemaError, match="revision '9999' was written by a newer Caretaker"):
        AuditLog(database.url)


def test_the_revisions_read_without_alembic_are_alembics() -> None:
    from alembic.script import ScriptDirectory

    scripts = ScriptDirectory.from_config(_config())
    assert _revisions() == {script.revision: script.down_revision for script in scripts.walk_revisions()}
    assert head_revision() == scripts.get_current_head()


def test_a_log_at_the_newest_revision_opens_without_alembic(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'audit.db'}"
    AuditLog(url).close()  # created at the newest revision
    code = (
        f"import sys; from records.audit_log import AuditLog; AuditLog({url!r}).close(); "
        "print(sorted(name for name in sys.modules if name.split('.')[0] in ('alembic', 'mako', 'pygments')))"
    )
    opened = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=COMMAND_HANG_S, check=True
    )
    assert opened.stdout == "[]\n", opened.stderr


def test_a_runner_cannot_upgrade_the_schema_and_is_told_who_can(postgres: PostgresServer) -> None:
    name = postgres.new_database()
    owner_url, runner_url = postgres.url(name, OWNER), postgres.url(name, RUNNER)
    _todays_log(owner_url)
    with pytest.raises(AuditSchemaError, match="the database owner runs: caretaker db upgrade --db OWNER_URL"):
        AuditLog(runner_url)
    status = caretaker("db", "status", "--db", runner_url)
    assert status.returncode == 0, status.stderr
    assert f"schema at revision 0001 (this Caretaker: {head_revision()})" in status.stdout
    upgraded = caretaker("db", "upgrade", "--db", owner_url)
    assert upgraded.returncode == 0 and f"schema at revision {head_revision()}" in upgraded.stdout, upgraded.stderr
    log = AuditLog(runner_url)
    assert log.verify("old-2").ok
    log.append(Event("old-2", 4, EventKind.RUN_RESUMED, "pax"))
    log.close()


def test_an_unreachable_database_is_reported_at_open_without_its_password(postgres: PostgresServer) -> None:
    closed_port = postgres.port + 1 if postgres.port < 65535 else postgres.port - 1
    url = f"postgresql://pax:secret@127.0.0.1:{closed_port}/caretaker"
    done = caretaker("report", "--list", "--db", url)
    assert done.returncode == 2
    assert "audit log postgresql+psycopg://pax:***@127.0.0.1" in done.stderr and "unavailable" in done.stderr
    assert "secret" not in done.stderr and "Traceback" not in done.stderr
