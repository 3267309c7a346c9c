"""Changes in the ground database as they happen: PostgreSQL NOTIFY, or a poll of the SQLite file.

A console must learn within a second that another process appended to a run, started, ended or
took over hosting a run, asked it to act, or changed an account. Notices name what changed; the
subscriber reads the rest from the tables (a notice is a wake-up, never the data). Channels and
payloads (the appending :class:`~records.audit_log.AuditLog` announces events after its commit;
the triggers of revision 0004 of :mod:`records.migrations` announce the rest):

=========== ================================= =================================================
channel     payload                           when
=========== ================================= =================================================
events      ``<seq> <kind> <run id>``         an audit record was appended
hosts       ``<run id>``                      a run's host row was created, removed, taken over
                                              or its published view changed
actions     ``<state> <request id> <host>``   an action request was made or changed state
accounts    ``<user id>``                     an account was changed or removed
handoffs    ``<state> <run id>``              an onboard run was handed to a supervisor, or its
                                              handoff changed state (:mod:`records.onboard_handoffs`)
resync      ``""``                            the feed lost the database and is back: notices may
                                              have been missed, so re-read what you show
=========== ================================= =================================================

PostgreSQL: one connection per process and database LISTENs, for every user of the feed in the
process (:func:`open_change_feed`: a supervisor's every run, a console's board); NOTIFY is
delivered at commit, so what a notice names is readable when it arrives. SQLite (one machine, no
NOTIFY): a thread reads the file every :data:`POLL_S` seconds and makes the same notices from
what changed since its last reading.
"""

from __future__ import annotations

import logging
import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import psycopg
import sqlalchemy as sa
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.exc import SQLAlchemyError

__all__ = ["POLL_S", "ChangeFeed", "ChangeNotice", "open_change_feed"]

log = logging.getLogger(__name__)

#: PostgreSQL channel -> the channel name subscribers see.
CHANNELS = {
    "caretaker_events": "events",
    "caretaker_hosts": "hosts",
    "caretaker_actions": "actions",
    "caretaker_accounts": "accounts",
    "caretaker_handoffs": "handoffs",
}
#: Seconds between readings of a SQLite file.
POLL_S = 0.25
_LONGEST_RETRY = 2.0

_records = sa.table("audit_records", sa.column("id"), sa.column("seq"), sa.column("kind"), sa.column("run_id"))
_hosts = sa.table("run_hosts", sa.column("run_id"), sa.column("host_id"), sa.column("view_seq"))
_requests = sa.table("run_action_requests", sa.column("id"), sa.column("state"), sa.column("host_id"))
_accounts = sa.table("console_accounts", sa.column("user_id"), sa.column("role"), sa.column("password_changed"))
_handoffs = sa.table("onboard_handoffs", sa.column("run_id"), sa.column("state"))


@dataclass(frozen=True)
class ChangeNotice:
    """Something changed: ``channel`` says what kind of thing, ``payload`` which one."""

    channel: str
    payload: str


Subscriber = Callable[[ChangeNotice], None]


class ChangeFeed:
    """One user's subscription to its process's watcher of a database (:func:`open_change_feed`).

    Every notice goes to its subscribers, from the watcher's thread: they must return quickly.
    :meth:`close` ends this subscription; the last one closed stops the watcher.
    """

    def __init__(self, watcher: _Watcher) -> None:
        self._watcher = watcher
        self._subscribers: list[Subscriber] = []
        self._closed = False

    @property
    def connected(self) -> threading.Event:
        """Set while the watcher reaches the database."""
        return self._watcher.connected

    def subscribe(self, subscriber: Subscriber) -> None:
        if self._closed:
            raise RuntimeError("this change feed is closed")
        self._subscribers.append(subscriber)
        self._watcher.subscribe(subscriber)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for subscriber in self._subscribers:
            self._watcher.unsubscribe(subscriber)
        _release(self._watcher)


class _Watcher(ABC):
    """Watches one database from a thread of its own and hands each notice to every subscriber.

    A subclass's :meth:`_run` is that thread: it watches the database until ``_closed`` is set.
    """

    def __init__(self, name: str) -> None:
        self._subscribers: list[Subscriber] = []
        self._lock = threading.Lock()
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self.connected = threading.Event()  # set while the feed reaches the database
        self.key = ""  # its database in _feeds
        self.users = 0  # open ChangeFeeds on it (under _feeds_lock)

    def start(self) -> _Watcher:
        self._thread.start()
        return self

    def subscribe(self, subscriber: Subscriber) -> None:
        with self._lock:
            self._subscribers.append(subscriber)

    def unsubscribe(self, subscriber: Subscriber) -> None:
        with self._lock:
            self._subscribers.remove(subscriber)

    def close(self) -> None:
        self._closed.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(5)

    def _publish(self, notice: ChangeNotice) -> None:
        with self._lock:
            subscribers = list(self._subscribers)
        for subscriber in subscribers:
            try:
                subscriber(notice)
            except Exception:  # one subscriber's bug must not starve the others
                log.exception("change feed subscriber %r failed on %s", subscriber, notice)

    @abstractmethod
    def _run(self) -> None:
        """Watch the database and :meth:`_publish` what changed, until ``_closed`` is set."""


class ListeningFeed(_Watcher):
    """PostgreSQL: LISTEN on every channel; reconnect with back-off, then say ``resync``."""

    def __init__(self, engine: Engine) -> None:
        super().__init__("change-feed-listen")
        self._conninfo = engine.url.set(drivername="postgresql").render_as_string(hide_password=False)
        self._location = engine.url.render_as_string(hide_password=True)

    def _run(self) -> None:
        delay, lost = 0.05, False
        while not self._closed.is_set():
            try:
                with psycopg.connect(
                    self._conninfo, autocommit=True, connect_timeout=5, application_name="caretaker-feed"
                ) as connection:
                    for channel in CHANNELS:
                        connection.execute(f"LISTEN {channel}")  # a constant of ours
                    self.connected.set()
                    if lost:
                        log.warning("change feed on %s is back", self._location)
                        self._publish(ChangeNotice("resync", ""))
                    delay, lost = 0.05, False
                    while not self._closed.is_set():
                        for note in connection.notifies(timeout=0.5):
                            self._publish(ChangeNotice(CHANNELS.get(note.channel, note.channel), note.payload))
            except psycopg.Error as exc:
                self.connected.clear()
                if not lost:
                    log.warning(
                        "change feed on %s lost the database (%s): retrying",
                        self._location,
                        str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__,
                    )
                lost = True
                self._closed.wait(delay)
                delay = min(delay * 2, _LONGEST_RETRY)


class PollingFeed(_Watcher):
    """SQLite: read what changed every :data:`POLL_S` s and publish the notices NOTIFY would have sent."""

    def __init__(self, engine: Engine) -> None:
        super().__init__("change-feed-poll")
        self._engine = engine
        self._last_event = 0
        self._hosts: dict[str, tuple[Any, ...]] = {}
        self._requests: dict[int, tuple[Any, ...]] = {}
        self._accounts: dict[str, tuple[Any, ...]] = {}
        self._handoffs: dict[str, str] = {}

    def _run(self) -> None:
        failing = False
        while not self._closed.is_set():
            try:
                with self._engine.connect() as connection:
                    notices = self._read(connection, announce=self.connected.is_set())
                self.connected.set()
                if failing:
                    notices.insert(0, ChangeNotice("resync", ""))
                failing = False
                for notice in notices:
                    self._publish(notice)
            except SQLAlchemyError as exc:
                if not failing:
                    log.warning("change feed cannot read %s: %s", self._engine.url, exc)
                failing = True
            self._closed.wait(POLL_S)

    def _read(self, connection: Connection, *, announce: bool) -> list[ChangeNotice]:
        """What changed since the last reading (the first reading only sets the baseline)."""
        notices: list[ChangeNotice] = []
        for row in connection.execute(
            sa.select(_records.c.id, _records.c.seq, _records.c.kind, _records.c.run_id)
            .where(_records.c.id > self._last_event)
            .order_by(_records.c.id)
        ):
            self._last_event = row.id
            notices.append(ChangeNotice("events", f"{row.seq} {row.kind} {row.run_id}"))
        hosts = {row.run_id: (row.host_id, row.view_seq) for row in connection.execute(sa.select(_hosts))}
        notices += [ChangeNotice("hosts", run) for run in _changed(self._hosts, hosts)]
        self._hosts = hosts
        floor = (
            min(
                [i for i, (state, _) in self._requests.items() if state in ("pending", "taken", "sent")]
                or [max(self._requests, default=0) + 1]
            )
            - 1
        )
        requests = {
            row.id: (row.state, row.host_id)
            for row in connection.execute(sa.select(_requests).where(_requests.c.id > floor))
        }
        notices += [
            ChangeNotice("actions", f"{requests[i][0]} {i} {requests[i][1]}")
            for i in _changed(self._requests, requests)
            if i in requests
        ]
        self._requests = requests
        accounts = {row.user_id: (row.role, row.password_changed) for row in connection.execute(sa.select(_accounts))}
        notices += [
            ChangeNotice("accounts", user) for user in _changed(self._accounts, accounts) if user in self._accounts
        ]
        self._accounts = accounts
        handoffs = {row.run_id: row.state for row in connection.execute(sa.select(_handoffs))}
        notices += [ChangeNotice("handoffs", f"{handoffs[run]} {run}") for run in _changed(self._handoffs, handoffs)]
        self._handoffs = handoffs
        return notices if announce else []


def _changed(before: dict[Any, Any], after: dict[Any, Any]) -> list[Any]:
    """Keys added, removed or whose value differs."""
    return [key for key in {*before, *after} if before.get(key) != after.get(key)]


#: The watchers of this process, by database: one connection LISTENs (or one thread polls) for all
#: the process's users of a database, however many runs it hosts (a supervisor: one per run).
_feeds: dict[str, _Watcher] = {}
_feeds_lock = threading.Lock()


def _key(engine: Engine) -> str:
    url = engine.url.render_as_string(hide_password=False)
    in_memory = engine.dialect.name == "sqlite" and engine.url.database in (None, "", ":memory:")
    return f"{url}#{id(engine)}" if in_memory else url  # each in-memory database is its engine's own


def open_change_feed(engine: Engine) -> ChangeFeed:
    """A subscription to the process's watcher of the database behind ``engine`` (LISTEN on
    PostgreSQL, polling on SQLite), started by the first and stopped by the last to close."""
    key = _key(engine)
    with _feeds_lock:
        watcher = _feeds.get(key)
        if watcher is None:
            watcher = ListeningFeed(engine) if engine.dialect.name == "postgresql" else PollingFeed(engine)
            watcher.key = key
            _feeds[key] = watcher.start()
        watcher.users += 1
    return ChangeFeed(watcher)


def _release(watcher: _Watcher) -> None:
    with _feeds_lock:
        watcher.users -= 1
        if watcher.users:
            return
        del _feeds[watcher.key]
    watcher.close()
