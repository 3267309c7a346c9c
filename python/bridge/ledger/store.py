"""The ledger's durable memory: one SQLite file of command keys and what became of them.

Every change is committed (``synchronous=FULL``) before the ledger answers, so an answer the
ground has seen is never forgotten by a crash. The file also holds the *epoch*: a random id
made when the memory is new (a new file) or loses records (retention pruning). A client that
re-sends a key under an older epoch cannot be told whether the key ran before the memory was
lost, so the ledger answers such a re-send UNKNOWN instead of running it a second time.

Retention: finished records older than ``retain_s`` are deleted (at open, then whenever
:meth:`LedgerStore.prune` runs), and deleting any of them starts a new epoch. Records in
progress are never pruned. The default (a week, ``caretaker ledger --retain-hours``) is far
longer than a run and its outage budget, so a run's keys outlive the run.
"""

from __future__ import annotations

import secrets
import sqlite3
import threading
import time
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

__all__ = ["LedgerStore", "LedgerStoreError", "Record", "State"]

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (name TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS commands (
    command_key TEXT PRIMARY KEY,
    service TEXT NOT NULL,
    type TEXT NOT NULL,
    request_json TEXT NOT NULL,
    state TEXT NOT NULL,
    response_json TEXT NOT NULL DEFAULT '',
    message TEXT NOT NULL DEFAULT '',
    started REAL NOT NULL,
    finished REAL
);
"""


class State(str, Enum):
    """What became of a command key."""

    IN_PROGRESS = "IN_PROGRESS"
    """The call is running now (in the ledger's memory only until it ends)."""
    SUCCEEDED = "SUCCEEDED"
    """The service answered, and its ``success`` field (if any) was not false."""
    FAILED = "FAILED"
    """The service answered with ``success`` false."""
    UNKNOWN = "UNKNOWN"
    """The call may have executed: no answer in time, its server left, or the ledger stopped during it."""
    REFUSED = "REFUSED"
    """Never executed: the request could not be made (bad input, no such service or server)."""


@dataclass(frozen=True)
class Record:
    """One command key's entry."""

    command_key: str
    service: str
    type: str
    request_json: str
    state: State
    response_json: str
    message: str
    started: float
    finished: float | None


class LedgerStoreError(Exception):
    """The state file cannot be used; the message names it and what to do."""

    def __init__(self, path: Path, reason: str) -> None:
        super().__init__(f"{path}: {reason}")
        self.path = path


class LedgerStore:
    """The SQLite file of one ledger. Thread-safe: every access holds ``_db_lock``.

    Opening it marks every call still recorded as in progress UNKNOWN: the ledger that ran
    them stopped before their answers came, so they may or may not have executed.

    Raises:
        LedgerStoreError: the file cannot be opened, is not a ledger database, or is damaged.
    """

    def __init__(self, path: Path, *, retain_s: float) -> None:
        self.path = path
        self.retain_s = retain_s
        self._db_lock = threading.Lock()
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._db = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None)
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")  # a committed outcome survives a crash of the host too
            self._db.executescript(_SCHEMA)
            row = self._db.execute("SELECT value FROM meta WHERE name = 'epoch'").fetchone()
        except (sqlite3.Error, OSError) as exc:
            raise LedgerStoreError(
                path,
                f"cannot use it as the ledger's state ({exc}); move it away to start"
                " with a new memory (clients then get UNKNOWN for keys they re-send)",
            ) from None
        self._epoch = str(row[0]) if row else self._new_epoch()
        self.interrupted = self._mark_interrupted()
        self.prune()

    @property
    def epoch(self) -> str:
        """The id of this memory; it changes whenever records were lost."""
        return self._epoch

    def _new_epoch(self) -> str:
        epoch = secrets.token_hex(8)
        self._db.execute("INSERT OR REPLACE INTO meta (name, value) VALUES ('epoch', ?)", (epoch,))
        self._epoch = epoch
        return epoch

    def _mark_interrupted(self) -> int:
        with self._db_lock:
            cursor = self._db.execute(
                "UPDATE commands SET state = ?, finished = ?, message = ? WHERE state = ?",
                (
                    State.UNKNOWN.value,
                    time.time(),
                    "the ledger stopped while this call was in progress; it may have executed",
                    State.IN_PROGRESS.value,
                ),
            )
            return cursor.rowcount

    def get(self, command_key: str) -> Record | None:
        """The record of ``command_key``, or None if this memory has none."""
        with self._db_lock:
            row = self._db.execute(
                "SELECT command_key, service, type, request_json, state, response_json, message, started, finished"
                " FROM commands WHERE command_key = ?",
                (command_key,),
            ).fetchone()
        if row is None:
            return None
        return Record(row[0], row[1], row[2], row[3], State(row[4]), row[5], row[6], row[7], row[8])

    def begin(self, command_key: str, service: str, type_name: str, request_json: str) -> None:
        """Record that ``command_key`` starts now (committed before the service is called)."""
        with self._db_lock:
            self._db.execute(
                "INSERT INTO commands (command_key, service, type, request_json, state, started)"
                " VALUES (?, ?, ?, ?, ?, ?)",
                (command_key, service, type_name, request_json, State.IN_PROGRESS.value, time.time()),
            )

    def finish(
        self, command_key: str, state: State, response_json: str, message: str, *, was: State = State.IN_PROGRESS
    ) -> bool:
        """Record the outcome of ``command_key`` if it is still in state ``was``; True if it was.

        ``was=State.UNKNOWN`` records an answer that came after the ledger gave up waiting.
        """
        with self._db_lock:
            cursor = self._db.execute(
                "UPDATE commands SET state = ?, response_json = ?, message = ?, finished = ?"
                " WHERE command_key = ? AND state = ?",
                (state.value, response_json, message, time.time(), command_key, was.value),
            )
            return cursor.rowcount == 1

    def prune(self) -> int:
        """Delete finished records older than the retention time; a new epoch if any went."""
        with self._db_lock:
            cursor = self._db.execute(
                "DELETE FROM commands WHERE state != ? AND finished < ?",
                (State.IN_PROGRESS.value, time.time() - self.retain_s),
            )
            if cursor.rowcount > 0:
                self._new_epoch()
            return cursor.rowcount

    def close(self) -> None:
        """Close the file; safe to call twice."""
        with self._db_lock:
            self._db.close()
