"""The consoles' own tables in the ground database, defined once.

Several consoles share one database (docs/ground-segment.md): the accounts they sign people in
with, which process hosts each live run (with its lease and the view it publishes), the newest
camera image of each hosted run, and operator actions forwarded to a run hosted elsewhere. The
console reads and writes them (:mod:`console.accounts`, :mod:`ground.run_hosts`,
:mod:`ground.action_requests`); revision 0004 of :mod:`records.migrations` creates them
from these definitions. So a later change to one of them is a new revision that looks at what
the database holds (as 0004 does for an accounts table made before it) and alters it.
"""

from __future__ import annotations

from sqlalchemy import Column, DateTime, Index, Integer, LargeBinary, MetaData, String, Table, Text

__all__ = ["console_accounts", "metadata", "run_action_requests", "run_camera_frames", "run_hosts"]

metadata = MetaData()
_WHEN = DateTime(timezone=True)

#: Who may sign in: ``caretaker accounts`` changes it, consoles read it.
console_accounts = Table(
    "console_accounts",
    metadata,
    Column("user_id", String(64), primary_key=True),
    Column("name", String(200), nullable=False, default=""),
    Column("role", String(16), nullable=False),
    Column("password_hash", String(255), nullable=False),
    Column("created", _WHEN, nullable=False),
    Column("password_changed", _WHEN, nullable=False),
)

#: Which process runs each live run's executive, its lease, and the view it publishes.
run_hosts = Table(
    "run_hosts",
    metadata,
    Column("run_id", String(120), primary_key=True),
    Column("host_id", String(64), nullable=False),
    Column("host", String(200), nullable=False),
    Column("binding", String(200), nullable=False),
    Column("started_by", String(120), nullable=False),
    Column("claimed", _WHEN, nullable=False),
    Column("lease_until", _WHEN, nullable=False),
    Column("status", String(16), nullable=False),
    Column("mode", String(16), nullable=False),
    Column("procedure_view", Text, nullable=False),
    Column("view", Text, nullable=False),
    Column("view_seq", Integer, nullable=False),
)

#: The newest camera image of each hosted run.
run_camera_frames = Table(
    "run_camera_frames",
    metadata,
    Column("run_id", String(120), primary_key=True),
    Column("version", String(64), nullable=False),
    Column("image", LargeBinary, nullable=False),
)

#: An operator action on a run hosted elsewhere, and its answer.
run_action_requests = Table(
    "run_action_requests",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("run_id", String(120), nullable=False),
    Column("host_id", String(64), nullable=False),
    Column("user_id", String(64), nullable=False),
    Column("console", String(200), nullable=False),
    Column("action", Text, nullable=False),
    Column("state", String(16), nullable=False),
    Column("requested", _WHEN, nullable=False),
    Column("status", Integer, nullable=True),
    Column("answer", Text, nullable=True),
    Column("answered", _WHEN, nullable=True),
    Index("ix_run_action_requests_host_state", "host_id", "state"),
)
