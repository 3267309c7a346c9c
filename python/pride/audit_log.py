"""The audit log: every action of every run, append-only, one committed row per action.

SQLAlchemy over any URL; a SQLite file (``var/caretaker.db``) by default, PostgreSQL for shared
deployments. Rows are only ever inserted; ``(run_id, seq)`` is unique, so a runner that somehow
tried to write an action twice fails loudly instead of duplicating history. Each append commits
before the run proceeds, so killing the runner loses nothing that was reported as done.
"""

from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from sqlalchemy import DateTime, Integer, String, Text, UniqueConstraint, create_engine, event, select
from sqlalchemy.engine import Engine
from sqlalchemy.orm import DeclarativeBase, Mapped, Session, mapped_column

from pride.events import Event, EventKind

__all__ = ["DEFAULT_DB", "AuditLog"]

DEFAULT_DB = "sqlite:///var/caretaker.db"


class _Base(DeclarativeBase):
    pass


class _Record(_Base):
    __tablename__ = "audit_records"
    __table_args__ = (UniqueConstraint("run_id", "seq", name="one_record_per_seq"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    run_id: Mapped[str] = mapped_column(String(120), index=True)
    seq: Mapped[int] = mapped_column(Integer)
    time: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    actor: Mapped[str] = mapped_column(String(120))
    kind: Mapped[str] = mapped_column(String(40))
    instruction: Mapped[str | None] = mapped_column(String(80), nullable=True)
    data: Mapped[str] = mapped_column(Text)


class AuditLog:
    """Append and read audit records. Safe to share between threads (one session per call)."""

    def __init__(self, url: str = DEFAULT_DB) -> None:
        if url.startswith("sqlite:///") and url != "sqlite:///:memory:":
            Path(url.removeprefix("sqlite:///")).parent.mkdir(parents=True, exist_ok=True)
        self.url = url
        self._engine: Engine = create_engine(url)
        if url.startswith("sqlite"):
            event.listen(self._engine, "connect", _sqlite_durability)
        _Base.metadata.create_all(self._engine)

    def append(self, record: Event) -> None:
        """Store one event and commit; raises if it cannot be stored."""
        with Session(self._engine) as session, session.begin():
            session.add(_Record(
                run_id=record.run_id, seq=record.seq, time=record.time, actor=record.actor, kind=record.kind.value,
                instruction=record.instruction, data=json.dumps(record.data, default=_json_default, sort_keys=True),
            ))

    def events(self, run_id: str) -> list[Event]:
        """Every event of a run, in order."""
        with Session(self._engine) as session:
            rows = session.scalars(select(_Record).where(_Record.run_id == run_id).order_by(_Record.seq)).all()
            return [_event(row) for row in rows]

    def runs(self) -> list[tuple[str, datetime, str]]:
        """(run id, start time, procedure id) of every run, oldest first."""
        with Session(self._engine) as session:
            rows = session.scalars(
                select(_Record).where(_Record.kind == EventKind.RUN_STARTED.value).order_by(_Record.time)
            ).all()
            return [(row.run_id, _utc(row.time), json.loads(row.data).get("procedure", "")) for row in rows]

    def close(self) -> None:
        self._engine.dispose()


def _sqlite_durability(connection: Any, _record: Any) -> None:
    cursor = connection.cursor()
    cursor.execute("PRAGMA synchronous=FULL")  # a commit survives a crash of the process (and the OS)
    cursor.close()


def _utc(moment: datetime) -> datetime:
    return moment if moment.tzinfo else moment.replace(tzinfo=timezone.utc)  # SQLite drops the zone


def _event(row: _Record) -> Event:
    return Event(row.run_id, row.seq, EventKind(row.kind), row.actor, row.instruction, json.loads(row.data), _utc(row.time))


def _json_default(value: Any) -> Any:
    if isinstance(value, (set, frozenset, tuple)):
        return list(value)
    return str(value)
