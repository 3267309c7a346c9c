"""Several consoles on one database: accounts, run hosts with leases, forwarded actions, change notices.

The tables are those of :mod:`records.console_tables`.

- ``console_accounts`` (:mod:`console.accounts`): consoles read it, the owner (``caretaker
  accounts``) changes it. A log whose accounts table the web view created before this revision
  keeps it as it is.
- ``run_hosts`` (:mod:`ground.run_hosts`): which process runs each live run's executive,
  its lease (renewed by heartbeats), and the view it publishes for other consoles;
  ``run_camera_frames``: the newest camera image of each hosted run.
- ``run_action_requests`` (:mod:`ground.action_requests`): an operator action on a run
  hosted elsewhere, and its answer.
- PostgreSQL: triggers NOTIFY the consoles (:mod:`ground.change_feed`) of changed hosts,
  requests and answers, and changed accounts (new events are announced by the appending process,
  after its commit: :class:`records.audit_log.AuditLog`); the runner role may read accounts and read
  and write the three tables.

Revision ID: 0004
Revises: 0002
"""

from __future__ import annotations

from alembic import op

from records import console_tables
from records.audit_schema import RUNNER_ROLE

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None

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
    # the tables as records.console_tables defines them; an accounts table the web view created
    # before this revision is kept as it is (checkfirst)
    console_tables.metadata.create_all(bind, checkfirst=True)
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
