"""``caretaker accounts`` on a database another process is writing: a clear refusal, nothing changed."""

from __future__ import annotations

import io
import sqlite3
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import event

import records.audit_log
from console.accounts import AccountStore
from console.accounts_command import main


def test_a_database_locked_past_the_wait_is_refused_with_the_reason(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "ground.db"
    store = AccountStore(f"sqlite:///{db}")
    try:
        store.add("bob", "operator", "first password", name="Bob")
    finally:
        store.close()
    monkeypatch.setattr(records.audit_log, "SQLITE_BUSY_TIMEOUT_S", 0.2)  # not the minute a console waits
    monkeypatch.setattr("sys.stdin", io.StringIO("second password\n"))
    writer = sqlite3.connect(db)
    try:
        writer.execute("BEGIN IMMEDIATE")  # another process holds the write lock, as a starved console may
        code = main(["--db", f"sqlite:///{db}", "set-password", "bob"])
    finally:
        writer.rollback()
        writer.close()
    err = capsys.readouterr().err
    assert code == 2, err
    assert "database is locked" in err and "nothing changed" in err and "Traceback" not in err
    store = AccountStore(f"sqlite:///{db}")
    try:
        assert store.verify("bob", "first password") is not None and store.verify("bob", "second password") is None
    finally:
        store.close()


def test_a_change_is_not_refused_because_a_console_wrote_between_its_read_and_its_write(tmp_path: Path) -> None:
    # A change reads its row, then writes it. Begun deferred on SQLite (WAL), a write committed
    # by another connection in between makes SQLite refuse the change at once, without waiting:
    # a console renewing its lease did that to a password change. A change takes the write lock
    # first, so nobody can write in between: the other writer is the one that finds it taken.
    db = tmp_path / "ground.db"
    store = AccountStore(f"sqlite:///{db}")
    others: list[str] = []

    def a_console_writes_meanwhile(conn: Any, cursor: Any, statement: str, *_: Any) -> None:
        if statement.startswith("UPDATE") and not others:
            console = sqlite3.connect(db, timeout=0)  # no wait: it writes now, or finds the lock taken
            try:
                console.execute("UPDATE console_accounts SET name = 'Alice A.' WHERE user_id = 'alice'")
                console.commit()
                others.append("written")
            except sqlite3.OperationalError as exc:
                others.append(str(exc))
            finally:
                console.close()

    try:
        store.add("alice", "operator", "alice's password", name="Alice")
        store.add("bob", "operator", "first password", name="Bob")
        event.listen(store._changes, "before_cursor_execute", a_console_writes_meanwhile)
        store.set_password("bob", "second password")
        assert others == ["database is locked"], others
        assert store.verify("bob", "second password") is not None
    finally:
        store.close()
