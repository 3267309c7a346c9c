"""The audit log's tables and how a database gets to them: Alembic migrations run at open.

:func:`ensure_schema` brings any audit-log database to the newest revision the running code
knows (scripts in :mod:`records.migrations`; no alembic.ini): an empty database gets the whole
schema, a log written before migrations existed (an ``audit_records`` table without the
``audit_schema_version`` table) is recognised as revision 0001 and upgraded in place. The
upgrade runs in one transaction under a lock (SQLite ``BEGIN IMMEDIATE``, a PostgreSQL advisory
lock), so two processes opening one database at once migrate it once.

On PostgreSQL the runner's role may only insert and read events, so it cannot migrate: a
database behind the code is upgraded by its owner (``caretaker db upgrade --db OWNER_URL``), and
a runner opening it meanwhile gets :class:`AuditSchemaError` saying so.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Column, DateTime, Integer, MetaData, String, Table, Text, UniqueConstraint, inspect
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.exc import DBAPIError

__all__ = [
    "RUNNER_ROLE",
    "VERSION_TABLE",
    "AuditSchemaError",
    "audit_records",
    "ensure_schema",
    "head_revision",
    "schema_revision",
]

log = logging.getLogger(__name__)

#: Alembic's version table (not the default name: a shared database may hold other applications).
VERSION_TABLE = "audit_schema_version"
#: PostgreSQL group role whose members may INSERT and SELECT events and nothing else.
RUNNER_ROLE = "caretaker_runner"
#: The revision of a log written before migrations existed.
LEGACY_REVISION = "0001"
_ADVISORY_LOCK = 0x63617265  # "care": serialises migrations of one PostgreSQL database

_MIGRATIONS = Path(__file__).resolve().parent / "migrations"
_metadata = MetaData()

#: The events table at the newest revision (the migrations are its history).
audit_records = Table(
    "audit_records",
    _metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("run_id", String(120), nullable=False, index=True),
    Column("seq", Integer, nullable=False),
    Column("time", DateTime(timezone=True), nullable=False),
    Column("actor", String(120), nullable=False),
    Column("kind", String(40), nullable=False),
    Column("instruction", String(80), nullable=True),
    Column("data", Text, nullable=False),
    Column("prev_hash", String(64), nullable=False),
    Column("hash", String(64), nullable=False),
    UniqueConstraint("run_id", "seq", name="one_record_per_seq"),
)


class AuditSchemaError(RuntimeError):
    """The database's schema cannot be used or upgraded by this connection; the message says what to do."""

    def __init__(self, url: str, revision: str | None, message: str) -> None:
        super().__init__(f"audit log {url}: {message}")
        self.url = url
        self.revision = revision


def _config(connection: Connection | None = None) -> Config:
    config = Config()
    config.set_main_option("script_location", str(_MIGRATIONS))
    config.attributes["connection"] = connection
    return config


def _scripts() -> ScriptDirectory:
    return ScriptDirectory.from_config(_config())


def head_revision() -> str:
    """The newest schema revision this code knows."""
    head = _scripts().get_current_head()
    assert head is not None, "records/migrations has no revisions"
    return head


def schema_revision(connection: Connection) -> str | None:
    """The database's revision: None when empty, :data:`LEGACY_REVISION` for a pre-migration log."""
    revision = MigrationContext.configure(connection, opts={"version_table": VERSION_TABLE}).get_current_revision()
    if revision is None and inspect(connection).has_table("audit_records"):
        return LEGACY_REVISION
    return revision


def ensure_schema(engine: Engine, url: str) -> None:
    """Upgrade the database behind ``engine`` to :func:`head_revision` if it is behind."""
    head = head_revision()
    scripts = _scripts()
    known = {script.revision for script in scripts.walk_revisions()}
    try:
        with engine.connect().execution_options(sqlite_begin="BEGIN IMMEDIATE") as connection, connection.begin():
            if connection.dialect.name == "postgresql":
                connection.exec_driver_sql(f"SELECT pg_advisory_xact_lock({_ADVISORY_LOCK})")
            revision = schema_revision(connection)
            if revision == head:
                return
            if revision is not None and revision not in known:
                raise AuditSchemaError(
                    url,
                    revision,
                    f"schema revision {revision!r} was written by a newer Caretaker "
                    f"(this one knows up to {head!r}); upgrade Caretaker",
                )
            config = _config(connection)
            if revision == LEGACY_REVISION and not _versioned(connection):
                log.warning("audit log %s predates schema migrations: upgrading it in place", url)
                command.stamp(config, LEGACY_REVISION)
            log.info("audit log %s: upgrading schema %s -> %s", url, revision, head)
            command.upgrade(config, "head")
    except DBAPIError as exc:
        if getattr(exc.orig, "sqlstate", None) == "42501":  # insufficient_privilege: a runner cannot migrate
            raise AuditSchemaError(
                url,
                None,
                f"its schema is behind this Caretaker (needs {head!r}) and this role "
                "may not upgrade it; the database owner runs: caretaker db upgrade "
                "--db OWNER_URL",
            ) from exc
        raise


def _versioned(connection: Connection) -> bool:
    return inspect(connection).has_table(VERSION_TABLE)


def sqlite_transactions(dbapi_connection: Any, _record: Any) -> None:
    """Let SQLAlchemy, not the sqlite3 module, begin transactions (so DDL is transactional too)."""
    dbapi_connection.isolation_level = None


def sqlite_begin(connection: Connection) -> None:
    """BEGIN as the connection's ``sqlite_begin`` option says (``BEGIN IMMEDIATE`` takes the write lock)."""
    connection.exec_driver_sql(connection.get_execution_options().get("sqlite_begin", "BEGIN"))
