"""The audit log's tables and how a database gets to them: Alembic migrations run at open.

:func:`ensure_schema` brings any audit-log database to the newest revision the running code
knows (scripts in :mod:`records.migrations`; no alembic.ini): an empty database gets the whole
schema, a log written before migrations existed (an ``audit_records`` table without the
``audit_schema_version`` table) is recognised as revision 0001 and upgraded in place. The
upgrade runs in one transaction under a lock (SQLite ``BEGIN IMMEDIATE``, a PostgreSQL advisory
lock), so two processes opening one database at once migrate it once.

Opening a database already at the newest revision, what nearly every process does, reads the
version table with SQLAlchemy and the revisions from the scripts' ``revision =`` lines, without
importing Alembic: Alembic brings Mako, Pygments and every SQL dialect with it, about a quarter of
a CPU-second at each start of ``caretaker run``, ``serve``, ``accounts`` or ``report``.

On PostgreSQL the runner's role may only insert and read events, so it cannot migrate: a
database behind the code is upgraded by its owner (``caretaker db upgrade --db OWNER_URL``), and
a runner opening it meanwhile gets :class:`AuditSchemaError` saying so.
"""

from __future__ import annotations

import ast
import logging
import re
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy import Column, DateTime, Integer, MetaData, String, Table, Text, UniqueConstraint, inspect, select
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.exc import DBAPIError

if TYPE_CHECKING:  # Alembic is imported only to upgrade
    from alembic.config import Config

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


#: Alembic's version table, as it makes it (read here without Alembic).
_versions = Table(VERSION_TABLE, MetaData(), Column("version_num", String(32), primary_key=True))
#: A script's ``revision = "0008"`` and ``down_revision = "0007"`` (or ``None``) lines.
_REVISION_LINE = re.compile(r"^(revision|down_revision)\s*(?::[^=]*)?=\s*(.+?)\s*$", re.MULTILINE)


class AuditSchemaError(RuntimeError):
    """The database's schema cannot be used or upgraded by this connection; the message says what to do."""

    def __init__(self, url: str, revision: str | None, message: str) -> None:
        super().__init__(f"audit log {url}: {message}")
        self.url = url
        self.revision = revision


def _config(connection: Connection | None = None) -> Config:
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", str(_MIGRATIONS))
    config.attributes["connection"] = connection
    return config


@cache
def _revisions() -> dict[str, str | None]:
    """Each revision of ``migrations/versions`` and the one it revises, as its script states them.

    The scripts form one line (records/migrations/__init__.py); tests/pride/test_audit_log.py
    checks that Alembic reads the same revisions and head from them.
    """
    revises: dict[str, str | None] = {}
    for script in sorted((_MIGRATIONS / "versions").glob("*.py")):
        stated = {name: ast.literal_eval(value) for name, value in _REVISION_LINE.findall(script.read_text())}
        if "revision" in stated:
            revises[stated["revision"]] = stated.get("down_revision")
    return revises


def head_revision() -> str:
    """The newest schema revision this code knows: the one no other revises."""
    revises = _revisions()
    heads = set(revises) - set(revises.values())
    assert len(heads) == 1, f"records/migrations must have one head, has {sorted(heads)}"
    return heads.pop()


def schema_revision(connection: Connection) -> str | None:
    """The database's revision: None when empty, :data:`LEGACY_REVISION` for a pre-migration log."""
    inspector = inspect(connection)
    if inspector.has_table(VERSION_TABLE):
        revisions: list[str] = list(connection.execute(select(_versions.c.version_num)).scalars())
        if len(revisions) > 1:
            url = connection.engine.url.render_as_string(hide_password=True)
            raise AuditSchemaError(url, None, f"its {VERSION_TABLE} holds {revisions}, not one revision")
        if revisions:
            return revisions[0]
    return LEGACY_REVISION if inspector.has_table("audit_records") else None


def ensure_schema(engine: Engine, url: str) -> None:
    """Upgrade the database behind ``engine`` to :func:`head_revision` if it is behind."""
    head = head_revision()
    try:
        with engine.connect().execution_options(sqlite_begin="BEGIN IMMEDIATE") as connection, connection.begin():
            if connection.dialect.name == "postgresql":
                connection.exec_driver_sql(f"SELECT pg_advisory_xact_lock({_ADVISORY_LOCK})")
            revision = schema_revision(connection)
            if revision == head:
                return
            if revision is not None and revision not in _revisions():
                raise AuditSchemaError(
                    url,
                    revision,
                    f"schema revision {revision!r} was written by a newer Caretaker "
                    f"(this one knows up to {head!r}); upgrade Caretaker",
                )
            from alembic import command

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
