"""A live run hosted by another process (another console, a runner), as this console shows it.

Everything comes from the ground database: the events from the audit log, the state, telemetry
and procedure from the view its host publishes, the camera image from the frame its host copies
(:mod:`ground.run_hosts`). The change feed marks it behind (a new event) or stale (a new
view); the watchers' send loops then :meth:`refresh` it, in a worker thread, and see the news. A
refresh that finds the host row gone (the run ended) or its lease run out (the host died) retires
it: the page then reloads it as a past run, interrupted and resumable if it did not end.

Actions on it are forwarded to its host (:mod:`ground.action_requests`), not done here.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from console.accounts import Account
from console.watchers import Watcher, Watchers
from ground.run_hosts import HostRecord, RunHosting
from pride.events import Event
from records.audit_log import AuditLog

__all__ = ["RemoteRun"]

#: A refresh reads the events even without a notice this often (s): a lost notice costs no more.
_SAFETY_REFRESH_S = 5.0


class RemoteRun:
    """One run hosted elsewhere, followed through the database."""

    def __init__(self, run_id: str, audit_log: AuditLog, hosting: RunHosting) -> None:
        self.run_id = run_id
        self._audit_log = audit_log
        self._hosting = hosting
        self._watchers = Watchers()
        self._lock = threading.Lock()  # guards what refresh() replaces
        self._refreshing = threading.Lock()  # one refresh at a time
        self._events: list[Event] = []
        self._record: HostRecord | None = None
        self._procedure_view: dict[str, Any] | None = None
        self._view: dict[str, Any] = {}
        self._behind = True
        self._stale = True
        self._read_at = 0.0
        self.retired = False

    # ---- news from the change feed (its thread) -------------------------------------------------
    def events_appended(self) -> None:
        self._behind = True
        self._watchers.wake()

    def host_changed(self) -> None:
        self._stale = True
        self._watchers.wake()

    # ---- reading the database (worker threads) ------------------------------------------------
    def refresh(self) -> None:
        """Read what changed: new events, the newest view, whether the host still holds the run."""
        with self._refreshing:
            safety = time.monotonic() - self._read_at > _SAFETY_REFRESH_S
            if self._behind or safety:
                self._behind = False
                with self._lock:
                    last = self._events[-1].seq if self._events else 0
                fresh = self._audit_log.events(self.run_id, after=last)
                with self._lock:
                    self._events.extend(fresh)
            if self._stale or safety or self._record is None:
                self._stale = False
                self._read_at = time.monotonic()
                published = self._hosting.published(self.run_id)
                with self._lock:
                    if published is None:
                        self._record = None
                    else:
                        self._record, self._procedure_view, self._view = published
            elif self._record is not None and self._record.lease_until.timestamp() < time.time():
                self._record = self._hosting.record(self.run_id)  # the lease looks run out: ask the database's clock
            record = self._record
        if record is None or not record.alive or record.host_id == self._hosting.host_id:
            self.retired = True  # ended, its host died, or it came here (resumed): the page reloads it
            self._watchers.wake()

    @property
    def record(self) -> HostRecord | None:
        return self._record

    @property
    def host_id(self) -> str:
        return self._record.host_id if self._record else ""

    @property
    def procedure_view(self) -> dict[str, Any] | None:
        return self._procedure_view

    # ---- watchers -----------------------------------------------------------------------------
    def watch(self, account: Account) -> Watcher:
        return self._watchers.add(account)

    def unwatch(self, watcher: Watcher) -> None:
        self._watchers.remove(watcher)
        self._watchers.wake()

    def watched(self) -> bool:
        return len(self._watchers) > 0

    # ---- views --------------------------------------------------------------------------------
    def events_since(self, seq: int) -> list[Event]:
        with self._lock:
            return [e for e in self._events if e.seq > seq]

    def state_json(self) -> dict[str, Any]:
        """The host's view of the run, with who watches it here and there, and where it runs."""
        with self._lock:
            state = dict(self._view.get("state") or {})
            record = self._record
        there = {w["user"]: w for w in state.get("watchers") or []}
        here = {w["user"]: w for w in self._watchers.people()}
        state.update(
            run_id=self.run_id,
            live=True,
            hosted_here=False,
            watchers=[v for _, v in sorted({**there, **here}.items())],
            host=record.host if record else "",
            lease_until=record.lease_until.isoformat() if record else None,
        )
        return state

    def telemetry_json(self) -> dict[str, Any]:
        with self._lock:
            telemetry = self._view.get("telemetry")
        return telemetry if isinstance(telemetry, dict) else {"readings": [], "checks": {}}

    def camera_image(self) -> bytes | None:
        return self._hosting.camera_frame(self.run_id)
