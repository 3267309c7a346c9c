"""Several consoles on one database: accounts, run hosts with leases, forwarded actions, change notices.

- ``console_accounts`` (:mod:`console.accounts`): consoles read it, the owner (``caretaker
  accounts``) changes it. A log whose accounts table the web view created before this revision
  keeps it as it is.
- ``run_hosts`` (:mod:`console.ground.run_hosts`): which process runs each live run's executive,
  its lease (renewed by heartbeats), and the view it publishes for other consoles;
  ``run_camera_frames``: the newest camera image of each hosted run.
- ``run_action_requests`` (:mod:`console.ground.action_requests`): an operator action on a run
  hosted elsewhere, and its answer.
- PostgreSQL: triggers NOTIFY the consoles (:mod:`console.ground.change_feed`) of changed hosts,
  requests and answers, and changed accounts (new events are announced by the appending process,
  after its commit: :class:`pride.audit_log.AuditLog`); the runner role may read accounts and read
  and write the three tables.

Revision ID: 0004
Revises: 0002
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from pride.audit_schema import RUNNER_ROLE

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None

_WHEN = sa.DateTime(timezone=True)

#: table -> what the runner role may do with it
_GRANTS = {
    "console_accounts": "SELECT",
    "run_hosts": "SELECT, INSERT, UPDATE, DELETE",
    "run_camera_frames": "SELECT, INSERT, UPDATE, DELETE",
    "run_action_requests": "SELECT, INSERT, UPDATE",
}

#: (trigger, table, timing and condition, channel, payload expression): what each NOTIFY says
_NOTICES = [
    (
        "run_hosts_notify_change",
        "run_hosts",
        "AFTER INSERT OR DELETE",
        "caretaker_hosts",
        "COALESCE(NEW.run_id, OLD.run_id)",
    ),
    ("run_hosts_notify_view", "run_hosts", "AFTER UPDATE OF host_id, view_seq", "caretaker_hosts", "NEW.run_id"),
    (
        "run_action_requests_notify",
        "run_action_requests",
        "AFTER INSERT OR UPDATE OF state",
        "caretaker_actions",
        "NEW.state || ' ' || NEW.id || ' ' || NEW.host_id",
    ),
    ("console_accounts_notify", "console_accounts", "AFTER UPDATE OR DELETE", "caretaker_accounts", "OLD.user_id"),
]


def upgrade() -> None:
    bind = op.get_bind()
    if not sa.inspect(bind).has_table("console_accounts"):
        op.create_table(
            "console_accounts",
            sa.Column("user_id", sa.String(64), primary_key=True),
            sa.Column("name", sa.String(200), nullable=False),
            sa.Column("role", sa.String(16), nullable=False),
            sa.Column("password_hash", sa.String(255), nullable=False),
            sa.Column("created", _WHEN, nullable=False),
            sa.Column("password_changed", _WHEN, nullable=False),
        )
    op.create_table(
        "run_hosts",
        sa.Column("run_id", sa.String(120), primary_key=True),
        sa.Column("host_id", sa.String(64), nullable=False),
        sa.Column("host", sa.String(200), nullable=False),
        sa.Column("binding", sa.String(200), nullable=False),
        sa.Column("started_by", sa.String(120), nullable=False),
        sa.Column("claimed", _WHEN, nullable=False),
        sa.Column("lease_until", _WHEN, nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("mode", sa.String(16), nullable=False),
        sa.Column("procedure_view", sa.Text, nullable=False),
        sa.Column("view", sa.Text, nullable=False),
        sa.Column("view_seq", sa.Integer, nullable=False),
    )
    op.create_table(
        "run_camera_frames",
        sa.Column("run_id", sa.String(120), primary_key=True),
        sa.Column("version", sa.String(64), nullable=False),
        sa.Column("image", sa.LargeBinary, nullable=False),
    )
    op.create_table(
        "run_action_requests",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("run_id", sa.String(120), nullable=False),
        sa.Column("host_id", sa.String(64), nullable=False),
        sa.Column("user_id", sa.String(64), nullable=False),
        sa.Column("console", sa.String(200), nullable=False),
        sa.Column("action", sa.Text, nullable=False),
        sa.Column("state", sa.String(16), nullable=False),
        sa.Column("requested", _WHEN, nullable=False),
        sa.Column("status", sa.Integer, nullable=True),
        sa.Column("answer", sa.Text, nullable=True),
        sa.Column("answered", _WHEN, nullable=True),
    )
    op.create_index("ix_run_action_requests_host_state", "run_action_requests", ["host_id", "state"])
    op.create_index("ix_audit_records_kind", "audit_records", ["kind"])  # the runs list reads the run starts
    if bind.dialect.name == "postgresql":
        _postgresql_notices_and_grants()


def _postgresql_notices_and_grants() -> None:
    for trigger, table, timing, channel, payload in _NOTICES:
        op.execute(f"""
            CREATE FUNCTION {trigger}() RETURNS trigger LANGUAGE plpgsql AS $$
            BEGIN
                PERFORM pg_notify('{channel}', {payload});
                RETURN NULL;
            END $$""")
        op.execute(f"CREATE TRIGGER {trigger} {timing} ON {table} FOR EACH ROW EXECUTE FUNCTION {trigger}()")
    for table, privileges in _GRANTS.items():
        op.execute(f"REVOKE ALL ON {table} FROM PUBLIC")
        op.execute(f"GRANT {privileges} ON {table} TO {RUNNER_ROLE}")
    op.execute(f"GRANT USAGE ON SEQUENCE run_action_requests_id_seq TO {RUNNER_ROLE}")


def downgrade() -> None:
    raise NotImplementedError("the audit log is never downgraded: restore a backup instead")
