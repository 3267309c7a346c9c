"""The audit log in the procedure-side tests: databases to keep it in, and a journal that remembers.

Every suite that records runs runs on SQLite and on PostgreSQL (the ``new_database`` fixture of
tests/pride/conftest.py makes an :class:`AuditDatabase` of each kind in turn).
"""

from __future__ import annotations

import json
import sqlite3
from contextlib import closing
from dataclasses import dataclass
from typing import Any

from sqlalchemy import select

from pride.events import Event, EventKind
from records.audit_log import AuditLog, Availability
from records.audit_schema import audit_records
from support.postgres import PostgresServer

__all__ = ["AuditDatabase", "RecordedJournal", "attach_records"]


@dataclass
class AuditDatabase:
    """One empty-of-events audit-log database: ``url`` is the runner's, ``owner_url`` the schema owner's."""

    kind: str
    url: str
    owner_url: str
    server: PostgresServer | None = None
    name: str = ""

    def tamper(self, *statements: str) -> None:
        """Run SQL with every protection bypassed, as a database superuser (or the SQLite file's owner) could."""
        if self.server is not None:
            self.server.sql("SET session_replication_role = replica", *statements, database=self.name)
            return
        with closing(sqlite3.connect(self.url.removeprefix("sqlite:///"), isolation_level=None)) as connection:
            connection.execute("DROP TRIGGER audit_records_no_update")
            connection.execute("DROP TRIGGER audit_records_no_delete")
            for statement in statements:
                connection.execute(statement)


class RecordedJournal:
    """The audit log as the executive's journal, remembering what went through it for assertions."""

    def __init__(self, log: AuditLog) -> None:
        self.log = log
        self.events: list[Event] = []
        self.stored_before: list[Event] = []
        self.fail_with: Exception | None = None  # set to make every append fail (a runner's last moments)

    def append(self, event: Event) -> None:
        if self.fail_with is not None:
            raise self.fail_with
        self.log.append(event)
        self.events.append(event)

    @property
    def availability(self) -> Availability:
        return self.log.availability

    def kinds(self, number: str | None = None) -> list[EventKind]:
        return [e.kind for e in self.events if number is None or e.instruction == number]


def attach_records(log: AuditLog, run_id: str) -> list[tuple[str, str, dict[str, Any]]]:
    """(kind, actor, data) of each record of an attach to onboard run ``run_id``, oldest first:
    each is the only event of an id of its own, ``<run_id>-attach-<UTC>-<hex>``."""
    with log.engine.connect() as connection:
        rows = connection.execute(
            select(audit_records.c.kind, audit_records.c.actor, audit_records.c.data)
            .where(audit_records.c.run_id.startswith(f"{run_id}-attach-", autoescape=True))
            .order_by(audit_records.c.time)
        ).all()
    return [(row.kind, row.actor, json.loads(row.data)) for row in rows]
