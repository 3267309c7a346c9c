"""``caretaker accounts`` on a database another process is writing: a clear refusal, nothing changed."""

from __future__ import annotations

import io
import sqlite3
from pathlib import Path

import pytest

import pride.audit_log
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
    monkeypatch.setattr(pride.audit_log, "SQLITE_BUSY_TIMEOUT_S", 0.2)  # not the minute a console waits
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
