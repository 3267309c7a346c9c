"""Which process hosts each live run, under a lease it renews, and the view of the run it publishes.

A run is *hosted* by the process that runs its executive (a console, ``caretaker serve``, or a
runner). The host claims the run's row in ``run_hosts`` when the run starts or resumes; a thread
republishes the run's view at every change and at least every :data:`PUBLISH_PERIOD_S` seconds,
each time renewing the lease (``lease_until``, on the database's clock, so the hosts' clocks do
not matter); the host removes the row when the run ends. Other consoles read the row to know the
run is live, who hosts it and what it looks like (``view``: what the host's page draws;
``procedure_view``: the procedure), and ``run_camera_frames`` for its newest camera image.

A row whose lease ran out belongs to a host that died or lost the database: the run is
interrupted, and any console may resume it, which claims the row anew (atomically: a row lock on
PostgreSQL, ``BEGIN IMMEDIATE`` on SQLite). A host whose renewal finds its row gone or claimed by
another has lost the run, and its ``on_lost`` listeners are told.
"""

from __future__ import annotations

import json
import logging
import secrets
import threading
import time
from collections.abc import Callable, Collection
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from sqlalchemy import delete, func, insert, select, update
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.exc import IntegrityError, SQLAlchemyError

from records.audit_chain import utc
from records.console_tables import run_camera_frames, run_hosts

__all__ = [
    "DEFAULT_LEASE_S",
    "live_runs",
    "HostRecord",
    "HostedElsewhere",
    "PublishedView",
    "RunHosting",
]

log = logging.getLogger(__name__)

#: Seconds a host's claim lasts without renewal: longer than a database restart should take, short
#: enough that the operators learn of a dead console while they can still act.
DEFAULT_LEASE_S = 10.0
#: The view is republished (telemetry ages) and the lease renewed at least this often (s).
PUBLISH_PERIOD_S = 1.0
#: Camera images are copied into the database at most this often per run (s).
FRAME_PERIOD_S = 1.0
_COALESCE_S = 0.05  # a burst of events is published once

_H = run_hosts.c
_SUMMARY = (_H.run_id, _H.host_id, _H.host, _H.binding, _H.started_by, _H.claimed, _H.lease_until, _H.status, _H.mode)


@dataclass(frozen=True)
class PublishedView:
    """What a host publishes of a run: the page's view of it, and its newest camera image (caption, file)."""

    view: dict[str, Any]
    status: str
    mode: str
    camera: tuple[dict[str, Any], Path] | None = None


ViewSource = Callable[[], PublishedView]
LostListener = Callable[[str, str], None]


@dataclass(frozen=True)
class HostRecord:
    """A run's host as the database has it; ``alive``: its lease had not run out when read."""

    run_id: str
    host_id: str
    host: str
    binding: str
    started_by: str
    claimed: datetime
    lease_until: datetime
    status: str
    mode: str
    alive: bool

    def to_json(self) -> dict[str, Any]:
        return {
            "host": self.host,
            "binding": self.binding,
            "started_by": self.started_by,
            "status": self.status,
            "mode": self.mode,
            "claimed": self.claimed.isoformat(),
            "lease_until": self.lease_until.isoformat(),
            "alive": self.alive,
        }


class HostedElsewhere(RuntimeError):
    """Another process holds a live lease on the run: ``record`` says which, until when."""

    def __init__(self, record: HostRecord) -> None:
        super().__init__(
            f"run {record.run_id} is live on {record.host} (its lease runs until "
            f"{record.lease_until:%H:%M:%S}Z and is being renewed)"
        )
        self.record = record


@dataclass
class _Hosted:
    source: ViewSource
    dirty: bool = True
    published: float = 0.0
    frame: dict[str, Any] | None = None  # caption of the image in run_camera_frames
    frame_time: float = 0.0


class RunHosting:
    """The runs this process hosts, and every host as the database has it. Thread-safe."""

    def __init__(self, engine: Engine, *, host: str, lease: float = DEFAULT_LEASE_S) -> None:
        if lease < 3 * PUBLISH_PERIOD_S:
            raise ValueError(
                f"a lease of {lease:g} s is too short: renewals come every {PUBLISH_PERIOD_S:g} s, "
                f"give at least {3 * PUBLISH_PERIOD_S:g} s"
            )
        self.host_id = secrets.token_hex(8)
        self.host = host[:200]
        self.lease = lease
        self._engine = engine
        self._lock = threading.Lock()  # guards _runs, _lost
        self._runs: dict[str, _Hosted] = {}
        self._lost: list[LostListener] = []
        self._wake = threading.Event()
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._run, name="run-hosting", daemon=True)
        self._thread.start()

    # ---- hosting ------------------------------------------------------------------------------
    def claim(
        self, run_id: str, *, binding: str, started_by: str, procedure_view: dict[str, Any], source: ViewSource
    ) -> None:
        """Host ``run_id`` here; HostedElsewhere if another process holds a live lease on it."""
        try:
            with (
                self._engine.connect().execution_options(sqlite_begin="BEGIN IMMEDIATE") as connection,
                connection.begin(),
            ):
                clock = _clock(connection)
                row = connection.execute(
                    select(*_SUMMARY, _H.view_seq).where(_H.run_id == run_id).with_for_update()
                ).first()
                if row is not None and row.host_id != self.host_id and utc(row.lease_until) > clock:
                    raise HostedElsewhere(_record(row, clock))
                values = {
                    "host_id": self.host_id,
                    "host": self.host,
                    "binding": binding[:200],
                    "started_by": started_by,
                    "claimed": clock,
                    "lease_until": clock + timedelta(seconds=self.lease),
                    "status": "active",
                    "mode": "",
                    "procedure_view": json.dumps(procedure_view, default=str),
                    "view": "{}",
                    "view_seq": (row.view_seq + 1) if row is not None else 1,
                }
                if row is None:
                    connection.execute(insert(run_hosts).values(run_id=run_id, **values))
                else:
                    connection.execute(update(run_hosts).where(_H.run_id == run_id).values(**values))
        except IntegrityError:  # another process inserted the row first
            record = self.record(run_id)
            if record is None:
                raise
            raise HostedElsewhere(record) from None
        with self._lock:
            self._runs[run_id] = _Hosted(source)
        self._wake.set()

    def changed(self, run_id: str) -> None:
        """The run's view changed: publish it soon. Cheap; any thread."""
        hosted = self._runs.get(run_id)
        if hosted is not None:
            hosted.dirty = True
            self._wake.set()

    def hosts(self, run_id: str) -> bool:
        """Whether this process hosts ``run_id``."""
        with self._lock:
            return run_id in self._runs

    def release(self, run_id: str) -> None:
        """The run ended here: remove its row (if still ours) and its camera frame."""
        with self._lock:
            self._runs.pop(run_id, None)
        with self._engine.begin() as connection:
            gone = connection.execute(delete(run_hosts).where(_H.run_id == run_id, _H.host_id == self.host_id)).rowcount
            if gone:
                connection.execute(delete(run_camera_frames).where(run_camera_frames.c.run_id == run_id))

    def lapse(self, run_id: str) -> None:
        """Stop hosting a run that goes on without this process (an onboard run's supervisor that
        stops; the habitat runs it): its row stays with its lease ended now, so the consoles show
        at once that nobody holds it, and which host did, and an attach may claim it. Call it
        after :meth:`close`: a renewal in flight would extend the lease once more."""
        with self._lock:
            self._runs.pop(run_id, None)
        with self._engine.begin() as connection:
            connection.execute(
                update(run_hosts)
                .where(_H.run_id == run_id, _H.host_id == self.host_id)
                .values(lease_until=_clock(connection), view_seq=_H.view_seq + 1)  # announced as a change
            )

    def on_lost(self, listener: LostListener) -> None:
        """Call ``listener(run_id, reason)`` when a run hosted here was claimed by another process."""
        with self._lock:
            self._lost.append(listener)

    def close(self) -> None:
        """Stop renewing (rows of runs still hosted stay, and their leases run out)."""
        self._closed.set()
        self._wake.set()
        self._thread.join(10)

    # ---- reading ------------------------------------------------------------------------------
    def records(self) -> dict[str, HostRecord]:
        """Every run's host row, by run id."""
        with self._engine.connect() as connection:
            clock = _clock(connection)
            return {row.run_id: _record(row, clock) for row in connection.execute(select(*_SUMMARY))}

    def views(self) -> tuple[list[tuple[HostRecord, dict[str, Any]]], datetime]:
        """Every hosted run's row and latest view, in one read (a console's fleet view of fifty runs),
        and the database's time of that read."""
        with self._engine.connect() as connection:
            clock = _clock(connection)
            rows = connection.execute(select(*_SUMMARY, _H.view)).all()
        return [(_record(row, clock), json.loads(row.view)) for row in rows], clock

    def record(self, run_id: str) -> HostRecord | None:
        with self._engine.connect() as connection:
            row = connection.execute(select(*_SUMMARY).where(_H.run_id == run_id)).first()
            return _record(row, _clock(connection)) if row is not None else None

    def published(self, run_id: str) -> tuple[HostRecord, dict[str, Any], dict[str, Any]] | None:
        """The host row, the procedure and the latest view of a hosted run (None: no row)."""
        with self._engine.connect() as connection:
            row = connection.execute(select(*_SUMMARY, _H.procedure_view, _H.view).where(_H.run_id == run_id)).first()
            if row is None:
                return None
            return _record(row, _clock(connection)), json.loads(row.procedure_view), json.loads(row.view)

    def onboard(self, run_id: str) -> bool:
        """Whether the run's host last published it as an onboard run (its view says what came down)."""
        published = self.published(run_id)
        state = published[2].get("state") if published is not None else None
        return isinstance(state, dict) and isinstance(state.get("onboard"), dict)

    def unsupervised(self, record: HostRecord) -> dict[str, Any]:
        """What the runs list adds to a run its log leaves interrupted and whose host row is ``record``:
        ``unsupervised`` (the supervisor that is gone, the binding) for an onboard run nobody holds,
        which an operator may attach a supervisor to (console/attach.py)."""
        if record.alive or not self.onboard(record.run_id):
            return {}
        return {"unsupervised": {"supervisor": record.host, "binding": record.binding}}

    def camera_frame(self, run_id: str) -> bytes | None:
        """The newest camera image the run's host copied into the database (PNG)."""
        with self._engine.connect() as connection:
            image: bytes | None = connection.scalar(
                select(run_camera_frames.c.image).where(run_camera_frames.c.run_id == run_id)
            )
            return image

    # ---- the renewing thread ----------------------------------------------------------------------
    def _run(self) -> None:
        failing = False
        while not self._closed.is_set():
            self._wake.wait(PUBLISH_PERIOD_S / 2)
            self._wake.clear()
            now = time.monotonic()
            with self._lock:
                due = [
                    (run, hosted)
                    for run, hosted in self._runs.items()
                    if hosted.dirty or now - hosted.published >= PUBLISH_PERIOD_S
                ]
            for run_id, hosted in due:
                hosted.dirty, hosted.published = False, now
                try:
                    self._publish(run_id, hosted)
                    failing = False
                except SQLAlchemyError as exc:
                    hosted.dirty = True
                    if not failing:
                        log.warning(
                            "cannot renew the lease of run %s (its lease runs out in %g s): %s",
                            run_id,
                            self.lease,
                            str(exc).splitlines()[0],
                        )
                    failing = True
                except Exception:  # the view's source failed: the lease must still be renewed next time
                    log.exception("publishing run %s", run_id)
            if due:
                self._closed.wait(_COALESCE_S)

    def _publish(self, run_id: str, hosted: _Hosted) -> None:
        published = hosted.source()
        frame = self._frame_due(hosted, published.camera)
        with self._engine.begin() as connection:
            clock = _clock(connection)
            if frame is not None:
                caption, image = frame
                connection.execute(delete(run_camera_frames).where(run_camera_frames.c.run_id == run_id))
                connection.execute(
                    insert(run_camera_frames).values(
                        run_id=run_id, version=str(caption.get("version", "")), image=image
                    )
                )
                hosted.frame, hosted.frame_time = caption, time.monotonic()
            view = {**published.view, "camera": hosted.frame}
            renewed = connection.execute(
                update(run_hosts)
                .where(_H.run_id == run_id, _H.host_id == self.host_id)
                .values(
                    view=json.dumps(view, default=str),
                    status=published.status,
                    mode=published.mode,
                    view_seq=_H.view_seq + 1,
                    lease_until=clock + timedelta(seconds=self.lease),
                )
            ).rowcount
        if not renewed:
            self._lose(run_id, "another process claimed the run after this one's lease ran out")

    def _frame_due(
        self, hosted: _Hosted, camera: tuple[dict[str, Any], Path] | None
    ) -> tuple[dict[str, Any], bytes] | None:
        """The camera image to copy now: a new one, and not more often than :data:`FRAME_PERIOD_S`."""
        if camera is None or (hosted.frame is not None and camera[0].get("version") == hosted.frame.get("version")):
            return None
        if time.monotonic() - hosted.frame_time < FRAME_PERIOD_S:
            hosted.dirty = True  # copy it at a later round
            return None
        try:
            return camera[0], camera[1].read_bytes()
        except OSError as exc:
            log.warning("camera image %s of a hosted run cannot be read: %s", camera[1], exc)
            return None

    def _lose(self, run_id: str, reason: str) -> None:
        with self._lock:
            self._runs.pop(run_id, None)
            listeners = list(self._lost)
        log.error("run %s is no longer hosted here: %s", run_id, reason)
        for listener in listeners:
            try:
                listener(run_id, reason)
            except Exception:
                log.exception("lost-run listener %r failed", listener)


def live_runs(engine: Engine, run_ids: Collection[str]) -> set[str]:
    """Which of ``run_ids`` a console, runner or supervisor hosts now (its lease not run out), read
    without holding anything (an agent asking whether a run without an end is running, a
    supervisor looking for runs whose supervisor is gone)."""
    if not run_ids:
        return set()
    with engine.connect() as connection:
        clock = _clock(connection)
        rows = connection.execute(select(_H.run_id, _H.lease_until).where(_H.run_id.in_(list(run_ids))))
        return {row.run_id for row in rows if utc(row.lease_until) > clock}


def _clock(connection: Connection) -> datetime:
    """Now, on the database's clock where it has one (PostgreSQL); one machine's clock for SQLite."""
    if connection.dialect.name == "postgresql":
        moment: datetime = connection.execute(select(func.now())).scalar_one()
        return utc(moment)
    return datetime.now(UTC)


def _record(row: Any, clock: datetime) -> HostRecord:
    until = utc(row.lease_until)
    return HostRecord(
        row.run_id,
        row.host_id,
        row.host,
        row.binding,
        row.started_by,
        utc(row.claimed),
        until,
        row.status,
        row.mode,
        until > clock,
    )
