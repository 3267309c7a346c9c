"""The audit log: every action of every run, append-only, tamper-evident, one commit per action.

SQLAlchemy over a SQLite file (``var/caretaker.db``, the default for one machine) or PostgreSQL
(``postgresql://role@host/db``, a shared ground segment; docs/ground-segment.md). The schema is
migrated at open (:mod:`records.audit_schema`). Rows are only ever inserted: triggers refuse
UPDATE and DELETE, and on PostgreSQL the runner's role holds no such grant.

Durability: :meth:`AuditLog.append` returns only after its transaction committed with the
database's full durability (SQLite in WAL mode with ``synchronous=FULL``: the WAL is fsynced at
every commit; PostgreSQL with its default ``synchronous_commit=on``). So killing the runner,
or the machine losing power, loses no event that was reported as done.

Tamper evidence: each event carries the hash of its run's previous event (:mod:`records.audit_chain`).
The last hash of every run this process writes stays in memory, so an append costs one INSERT
and no read; :meth:`AuditLog.verify` checks a run's chain.

When the database is unreachable (a PostgreSQL restart, a lost connection, a locked SQLite
file), :meth:`AuditLog.append` does not fail at once: it retries with back-off, in order, and
the run waits, for up to ``outage_budget`` seconds (:data:`DEFAULT_OUTAGE_BUDGET`). Availability
listeners hear "unavailable since T" and "available again" and the log says it. Past the budget
the append raises :class:`AuditLogUnavailable` and the executive stops the run with that reason;
``caretaker run --resume`` continues it once the database is back.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import logging
import os
import queue
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from sqlalchemy import create_engine, event, insert, make_url, select, text
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.exc import DBAPIError, IntegrityError, InterfaceError, OperationalError, SQLAlchemyError
from sqlalchemy.pool import StaticPool

from pride.event_payloads import EventDataError, payload_from_json
from pride.events import Availability, Event, EventKind
from records.audit_chain import GENESIS, ChainCheck, StoredEvent, utc, verify_chain
from records.audit_schema import audit_records, ensure_schema, schema_revision, sqlite_begin, sqlite_transactions

__all__ = [
    "DEFAULT_DB",
    "DEFAULT_OUTAGE_BUDGET",
    "AuditLog",
    "AuditLogUnavailable",
    "AuditSequenceError",
    "Availability",
    "database_url",
    "open_engine",
]

log = logging.getLogger(__name__)

DEFAULT_DB = "sqlite:///var/caretaker.db"
#: Seconds a run waits for an unreachable database before it stops (it can be resumed).
DEFAULT_OUTAGE_BUDGET = 120.0
_FIRST_RETRY = 0.05
_LONGEST_RETRY = 2.0
_RECORDS = audit_records.c
_COLUMNS = ("run_id", "seq", "time", "actor", "kind", "instruction", "data", "prev_hash", "hash")
_INSERT = insert(audit_records)


class AuditLogUnavailable(RuntimeError):
    """The database cannot be reached: at open, or for longer than the outage budget (the event was not stored)."""

    def __init__(self, url: str, error: str, *, since: datetime | None = None, waited: float | None = None) -> None:
        outage = f" since {since:%H:%M:%S}Z, gave up after {waited:g} s" if since and waited is not None else ""
        super().__init__(f"audit log {url} unavailable{outage}: {error}")
        self.url = url
        self.since = since


class AuditSequenceError(ValueError):
    """An event's sequence number is not the next of its run (a second writer, or a caller's bug)."""

    def __init__(self, run_id: str, seq: int, expected: int) -> None:
        super().__init__(f"run {run_id}: event {seq} is not the next event (expected {expected})")
        self.run_id = run_id
        self.seq = seq
        self.expected = expected


AvailabilityListener = Callable[[Availability], None]


def database_url(url: str) -> str:
    """``url`` as SQLAlchemy needs it: ``postgresql://`` and ``postgres://`` use psycopg 3."""
    for prefix in ("postgresql://", "postgres://"):
        if url.startswith(prefix):
            return "postgresql+psycopg://" + url.removeprefix(prefix)
    return url


class AuditLog:
    """Append and read audit records. Safe to share between threads; one writer per run."""

    def __init__(
        self, url: str = DEFAULT_DB, *, outage_budget: float = DEFAULT_OUTAGE_BUDGET, upgrade: bool = True
    ) -> None:
        """Open the log at ``url``; ``upgrade=False`` leaves the schema as it is (to inspect it only)."""
        self.url = url
        self.outage_budget = outage_budget
        self.location = make_url(database_url(url)).render_as_string(hide_password=True)  # for messages
        self._engine = open_engine(url)
        self._writers = _WriterQueue(_sqlite_file(database_url(url)))
        self._insert = _DriverInsert(self._engine, self._writers)
        try:
            if upgrade:
                ensure_schema(self._engine, self.location)
            else:
                self.schema_revision()  # reach the database now, as an upgrading open would
        except BaseException as exc:
            self._engine.dispose()
            self._writers.close()
            if isinstance(exc, (OperationalError, InterfaceError)):
                raise AuditLogUnavailable(self.location, _error_text(exc)) from exc
            raise
        self._heads: dict[str, tuple[int, str]] = {}  # run -> (seq, hash) of its last stored event
        self._run_locks: dict[str, threading.Lock] = {}
        self._lock = threading.Lock()
        self._availability = Availability(True)
        self._listeners: list[AvailabilityListener] = []
        self._closed = threading.Event()
        self._announcer = _Announcer(self._engine) if self._engine.dialect.name == "postgresql" else None

    @property
    def engine(self) -> Engine:
        """The engine the log reads with: the other tables of the ground database use it too."""
        return self._engine

    # ---- availability -----------------------------------------------------------------------
    @property
    def availability(self) -> Availability:
        return self._availability

    def add_availability_listener(self, listener: AvailabilityListener) -> None:
        """Call ``listener(Availability)`` when appends stop or start reaching the database.

        Called on the appending thread, which may hold the executive's lock: be quick, do not block.
        """
        with self._lock:
            self._listeners.append(listener)

    def _set_availability(self, state: Availability) -> None:
        with self._lock:
            if state.available == self._availability.available:
                return
            previous, self._availability = self._availability, state
            listeners = list(self._listeners)
        if state.available:
            assert previous.since is not None
            log.warning(
                "audit log %s available again after %.1f s",
                self.location,
                (datetime.now(UTC) - previous.since).total_seconds(),
            )
        else:
            log.warning(
                "audit log %s unavailable since %s: %s; runs wait for it (at most %g s)",
                self.location,
                f"{state.since:%H:%M:%S}Z",
                state.error,
                self.outage_budget,
            )
        for listener in listeners:
            try:
                listener(state)
            except Exception:  # an observer's bug must not stop the run's recording
                log.exception("audit availability listener %r failed", listener)

    # ---- writing ----------------------------------------------------------------------------
    def append(self, record: Event) -> None:
        """Store one event and commit; wait while the database is unreachable (see the module doc).

        Raises :class:`AuditSequenceError` if the event is not its run's next, IntegrityError if
        another writer stored that number first, :class:`AuditLogUnavailable` past the outage budget.
        """
        self.append_all([record])

    def append_all(self, records: Sequence[Event]) -> None:
        """Store consecutive events of one run in one transaction, all or none, as :meth:`append`
        stores one: what came down from a habitat in one answer costs one commit, not one each
        (a supervisor of fifty runs stored 300 events a second one by one, against 500 made)."""
        if not records:
            return
        run_id = records[0].run_id
        if any(record.run_id != run_id for record in records):
            raise ValueError("append_all stores the events of one run")
        with self._lock:
            run_lock = self._run_locks.setdefault(run_id, threading.Lock())
        with run_lock:
            prepared = [
                (record, utc(record.time), json.dumps(record.data.to_json(), default=_json_default, sort_keys=True))
                for record in records
            ]
            first_failure: float | None = None
            delay = _FIRST_RETRY
            while True:
                try:
                    rows = self._store(run_id, prepared, retrying=first_failure is not None)
                    break
                except (OperationalError, InterfaceError) as exc:  # the database, not the events: wait and retry
                    now = time.monotonic()
                    if first_failure is None:
                        first_failure = now
                        since = self._availability.since or datetime.now(UTC)
                        self._set_availability(Availability(False, since, _error_text(exc)))
                    if now - first_failure >= self.outage_budget or self._closed.is_set():
                        self._heads.pop(run_id, None)  # the last commit's fate is unknown: re-read it
                        raise AuditLogUnavailable(
                            self.location, _error_text(exc), since=self._availability.since, waited=now - first_failure
                        ) from exc
                    self._closed.wait(min(delay, self.outage_budget - (now - first_failure)))
                    delay = min(delay * 2, _LONGEST_RETRY)
            self._heads[run_id] = (rows[-1].seq, rows[-1].hash)
        if self._announcer is not None:
            for record in records:
                self._announcer.announce(f"{record.seq} {record.kind.value} {record.run_id}")
        if not self._availability.available:
            self._set_availability(Availability(True))

    def _store(self, run_id: str, prepared: list[tuple[Event, datetime, str]], *, retrying: bool) -> list[StoredEvent]:
        head = self._heads.get(run_id)
        if head is None:
            with self._engine.connect() as connection:
                head = _head(connection, run_id)
        rows = []
        for record, moment, data in prepared:
            if record.seq != head[0] + 1:
                raise AuditSequenceError(run_id, record.seq, head[0] + 1)
            unlinked = StoredEvent(
                run_id, record.seq, moment, record.actor, record.kind.value, record.instruction, data, prev_hash=head[1]
            )
            rows.append(replace(unlinked, hash=unlinked.expected_hash()))
            head = (rows[-1].seq, rows[-1].hash)
        try:
            self._insert(rows)
        except IntegrityError:
            if retrying and self._stored_hash(run_id, rows[-1].seq) == rows[-1].hash:
                return rows  # the attempt whose answer the outage swallowed did commit (all of it: one transaction)
            raise
        return rows

    def _stored_hash(self, run_id: str, seq: int) -> str | None:
        with self._engine.connect() as connection:
            return connection.scalar(select(_RECORDS.hash).where(_RECORDS.run_id == run_id, _RECORDS.seq == seq))

    # ---- reading ----------------------------------------------------------------------------
    def events(self, run_id: str, *, after: int = 0) -> list[Event]:
        """Every event of a run, in order; ``after``: only those with a greater sequence number."""
        return [_event(row) for row in self.stored_events(run_id, after=after)]

    def verify(self, run_id: str) -> ChainCheck:
        """Check the run's hash chain as stored (see :mod:`records.audit_chain`)."""
        return verify_chain(run_id, self.stored_events(run_id))

    def stored_events(self, run_id: str, *, after: int = 0) -> list[StoredEvent]:
        """A run's records as stored, with their hashes, in order (those numbered above ``after``)."""
        with self._engine.connect() as connection:
            rows = connection.execute(
                select(
                    _RECORDS.run_id,
                    _RECORDS.seq,
                    _RECORDS.time,
                    _RECORDS.actor,
                    _RECORDS.kind,
                    _RECORDS.instruction,
                    _RECORDS.data,
                    _RECORDS.prev_hash,
                    _RECORDS.hash,
                )
                .where(_RECORDS.run_id == run_id, _RECORDS.seq > after)
                .order_by(_RECORDS.seq)
            )
            return [StoredEvent(*row) for row in rows]

    def schema_revision(self) -> str | None:
        with self._engine.connect() as connection:
            return schema_revision(connection)

    def runs(self) -> list[tuple[str, datetime, str]]:
        """(run id, start time, procedure id) of every run, oldest first."""
        return [(run_id, started, str(data.get("procedure", ""))) for run_id, started, data in self.starts()]

    def starts(self) -> list[tuple[str, datetime, dict[str, Any]]]:
        """(run id, start time, its ``run_started`` data as stored) of every run, oldest first."""
        with self._engine.connect() as connection:
            rows = connection.execute(
                select(_RECORDS.run_id, _RECORDS.time, _RECORDS.data)
                .where(_RECORDS.kind == EventKind.RUN_STARTED.value)
                .order_by(_RECORDS.time)
            )
            return [(row.run_id, utc(row.time), json.loads(row.data)) for row in rows]

    def close(self) -> None:
        """Release the connections; an append still waiting for the database gives up."""
        self._closed.set()
        if self._announcer is not None:
            self._announcer.close()
        self._engine.dispose()
        self._writers.close()


class _DriverInsert:
    """The appends' INSERTs, committed together, straight through the driver (sqlite3, psycopg) of a pooled connection.

    Not through SQLAlchemy's statement machinery, whose CPU (about 0.15 ms an append) doubled
    what a runner spends per event: on a loaded machine that is time in which it gets descheduled,
    on SQLite inside its writer's turn, holding up every other runner (docs/benchmarks.md).
    PostgreSQL: one INSERT in autocommit is its own transaction, one round trip; several go in one
    transaction (psycopg pipelines them). SQLite: BEGIN, the INSERTs, COMMIT during the writer's
    turn (see :class:`_WriterQueue`).
    """

    def __init__(self, engine: Engine, writers: _WriterQueue) -> None:
        self._engine = engine
        self._writers = writers
        self._sqlite = engine.dialect.name == "sqlite"
        self._dbapi = engine.dialect.loaded_dbapi
        self._sql = str(_INSERT.compile(dialect=engine.dialect, column_keys=list(_COLUMNS)))
        self._positional = engine.dialect.positional
        self._time = audit_records.c.time.type.dialect_impl(engine.dialect).bind_processor(engine.dialect)

    def __call__(self, rows: list[StoredEvent]) -> None:
        parameters = [self._parameters(row) for row in rows]
        try:
            connection = (
                self._engine.raw_connection()
            )  # sqlite3 connections BEGIN by hand (audit_schema.sqlite_transactions)
        except self._dbapi.Error as exc:  # the pool hands the driver's error on as it is
            raise DBAPIError.instance(None, None, exc, self._dbapi.Error) from exc
        try:
            with self._writers.turn():
                cursor = connection.cursor()
                try:
                    if self._sqlite:
                        cursor.execute("BEGIN")
                        cursor.executemany(self._sql, parameters)
                        connection.commit()
                    elif len(parameters) > 1:
                        cursor.executemany(self._sql, parameters)
                        connection.commit()
                    else:
                        driver: Any = connection.driver_connection
                        driver.autocommit = True
                        try:
                            cursor.execute(self._sql, parameters[0])
                        finally:  # the pool's other users expect transactions; a broken connection is dropped below
                            with contextlib.suppress(self._dbapi.Error):
                                driver.autocommit = False
                finally:
                    cursor.close()
        except self._dbapi.Error as exc:
            if isinstance(exc, (self._dbapi.OperationalError, self._dbapi.InterfaceError)):
                connection.invalidate(exc)  # a broken or doubtful connection is not given out again
            else:
                connection.rollback()
            raise DBAPIError.instance(self._sql, parameters, exc, self._dbapi.Error) from exc
        finally:
            connection.close()

    def _parameters(self, row: StoredEvent) -> Any:
        values = {name: getattr(row, name) for name in _COLUMNS}
        if self._time is not None:
            values["time"] = self._time(row.time)
        return tuple(values[name] for name in _COLUMNS) if self._positional else values


class _Announcer:
    """NOTIFY ``caretaker_events`` of committed appends, for the consoles (:mod:`ground.change_feed`).

    Not in the append's own transaction (a trigger): PostgreSQL holds a database-wide lock from a
    notifying transaction's commit to its end, fsync included, so with four runners appending flat
    out their commits went one at a time (p95 15 ms against 4 ms; docs/benchmarks.md). Here the
    notices of a burst go out together, from a thread of their own, once the events are durable.
    A notice lost (the database went away, the process died) costs a console at most its periodic
    re-read of the run.
    """

    _SQL = text("SELECT pg_notify('caretaker_events', :payload)")

    def __init__(self, engine: Engine) -> None:
        self._engine = engine
        self._queue: queue.SimpleQueue[str | None] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._run, name="audit-announcer", daemon=True)
        self._thread.start()

    def announce(self, payload: str) -> None:
        self._queue.put(payload)

    def close(self) -> None:
        self._queue.put(None)
        self._thread.join(5)

    def _run(self) -> None:
        failing = False
        while True:
            batch = [self._queue.get()]
            while not self._queue.empty() and batch[-1] is not None:
                batch.append(self._queue.get())
            payloads = [{"payload": payload} for payload in batch if payload is not None]
            if payloads:
                try:
                    with self._engine.begin() as connection:
                        connection.execute(self._SQL, payloads)
                    failing = False
                except SQLAlchemyError as exc:
                    if not failing:
                        log.warning("cannot announce new events to the consoles: %s", _error_text(exc))
                    failing = True
            if batch[-1] is None:
                return


class _WriterQueue:
    """Writers of one SQLite file take turns in the kernel (``flock`` on ``<file>.append-lock``).

    SQLite's own busy handler polls with sleeps of 1, 2, 5, 10, ... ms: with four runners on one
    file that put the p99 append at 34 ms (docs/benchmarks.md). Waiting on a file lock wakes the
    next writer as soon as the commit ends. PostgreSQL needs no queue (inserts do not block each other).
    """

    def __init__(self, database: Path | None) -> None:
        self._threads = threading.Lock()  # flock does not order threads sharing one descriptor
        self._fd = os.open(f"{database}.append-lock", os.O_CREAT | os.O_RDWR, 0o644) if database else None

    @contextlib.contextmanager
    def turn(self) -> Iterator[None]:
        if self._fd is None:
            yield
            return
        with self._threads:
            fcntl.flock(self._fd, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(self._fd, fcntl.LOCK_UN)

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def _sqlite_file(url: str) -> Path | None:
    """The file of a SQLite URL (None for PostgreSQL and in-memory databases)."""
    if not url.startswith("sqlite") or url in ("sqlite://", "sqlite:///:memory:"):
        return None
    return Path(url.removeprefix("sqlite:///"))


#: s a SQLite connection waits for another's write lock before "database is locked". Consoles,
#: runs and the accounts command share one file; a writer starved of the CPU mid-transaction holds
#: the lock as long as it is starved (past 10 s under load: a password change then failed).
SQLITE_BUSY_TIMEOUT_S = 60.0


def open_engine(url: str) -> Engine:
    """An engine on the ground database at ``url`` (any form :func:`database_url` takes), set up as the
    audit log needs it: a connect timeout on PostgreSQL; on SQLite WAL, full durability, and
    transactions begun by SQLAlchemy (see :mod:`records.audit_schema`)."""
    url = database_url(url)
    if not url.startswith("sqlite"):
        return create_engine(url, connect_args={"connect_timeout": 5, "application_name": "caretaker"})
    database = _sqlite_file(url)
    if database is not None:
        database.parent.mkdir(parents=True, exist_ok=True)
    connect_args = {"timeout": SQLITE_BUSY_TIMEOUT_S, "check_same_thread": False}
    engine = (
        create_engine(url, poolclass=StaticPool, connect_args=connect_args)
        if database is None
        else create_engine(url, connect_args=connect_args)
    )
    event.listen(engine, "connect", sqlite_transactions)
    event.listen(engine, "connect", _sqlite_durability)
    event.listen(engine, "begin", sqlite_begin)
    return engine


def _sqlite_durability(connection: Any, _record: Any) -> None:
    cursor = connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")  # readers (reports, the web view) never block the writer
    cursor.execute("PRAGMA synchronous=FULL")  # WAL fsynced at each commit: survives a crash and a power loss
    cursor.close()


def _head(connection: Connection, run_id: str) -> tuple[int, str]:
    last = connection.execute(
        select(_RECORDS.seq, _RECORDS.hash).where(_RECORDS.run_id == run_id).order_by(_RECORDS.seq.desc()).limit(1)
    ).first()
    return (0, GENESIS) if last is None else (last.seq, last.hash)


def _event(row: StoredEvent) -> Event:
    kind = EventKind(row.kind)
    try:
        data = payload_from_json(kind, json.loads(row.data))
    except EventDataError as exc:  # edited in the database, or written by something else: say which
        raise EventDataError(f"run {row.run_id}, event {row.seq}: {exc}") from None
    return Event(row.run_id, row.seq, kind, row.actor, row.instruction, data, utc(row.time))


def _error_text(exc: Exception) -> str:
    """The driver's first line of the error (SQLAlchemy appends the statement and a link)."""
    text = str(getattr(exc, "orig", None) or exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _json_default(value: Any) -> Any:
    if isinstance(value, (set, frozenset, tuple)):
        return list(value)
    return str(value)
