"""Onboard runs handed to a supervising ground process (:mod:`records.onboard_handoffs`).

``onboard_handoffs`` holds, per run id, the unit a runner handed over, which supervisor took it
and how supervision ended. PostgreSQL: a trigger NOTIFYs ``caretaker_handoffs`` with ``<state>
<run id>`` when a row is added or its state changes (the supervisors and the waiting runner listen,
:mod:`ground.change_feed`); the runner role may read, add and update rows.

Revision ID: 0006
Revises: 0005
"""

from __future__ import annotations

from alembic import op

from records.audit_schema import RUNNER_ROLE
from records.onboard_handoffs import onboard_handoffs

revision = "0006"
down_revision = "0005"
branch_labels = None
depends_on = None


def upgrade() -> None:
    bind = op.get_bind()
    onboard_handoffs.create(bind)
    if bind.dialect.name == "postgresql":
        op.execute("""
            CREATE FUNCTION onboard_handoffs_notify() RETURNS trigger LANGUAGE plpgsql AS $$
            BEGIN
                PERFORM pg_notify('caretaker_handoffs', NEW.state || ' ' || NEW.run_id);
                RETURN NULL;
            END $$""")
        op.execute(
            "CREATE TRIGGER onboard_handoffs_notify AFTER INSERT OR UPDATE OF state ON onboard_handoffs "
            "FOR EACH ROW EXECUTE FUNCTION onboard_handoffs_notify()"
        )
        op.execute("REVOKE ALL ON onboard_handoffs FROM PUBLIC")
        op.execute(f"GRANT SELECT, INSERT, UPDATE ON onboard_handoffs TO {RUNNER_ROLE}")


def downgrade() -> None:
    raise NotImplementedError("the audit log is never downgraded: restore a backup instead")
