"""Assistant agents: their tokens, the runs they propose and the record of their calls (:mod:`records.agent_tables`).

``agent_records`` is append-only as ``audit_records`` is: triggers refuse UPDATE and DELETE (and
TRUNCATE on PostgreSQL) for everyone. PostgreSQL: the runner role (``caretaker agent`` connects
as one) may read tokens, read, add and update proposals, read and add records; tokens are
written by the owner (``caretaker accounts token``).

Revision ID: 0007
Revises: 0006
"""

from __future__ import annotations

from alembic import op

from records.agent_tables import metadata
from records.audit_schema import RUNNER_ROLE

revision = "0007"
down_revision = "0006"
branch_labels = None
depends_on = None

#: table -> what the runner role may do with it
_GRANTS = {
    "agent_tokens": "SELECT",
    "agent_proposals": "SELECT, INSERT, UPDATE",
    "agent_records": "SELECT, INSERT",
}


def upgrade() -> None:
    bind = op.get_bind()
    metadata.create_all(bind)
    if bind.dialect.name == "postgresql":
        op.execute("""
            CREATE FUNCTION agent_records_append_only() RETURNS trigger LANGUAGE plpgsql AS $$
            BEGIN
                RAISE EXCEPTION 'agent records are append-only (% refused)', TG_OP
                    USING ERRCODE = 'insufficient_privilege';
            END $$""")
        op.execute(
            "CREATE TRIGGER agent_records_append_only BEFORE UPDATE OR DELETE ON agent_records "
            "FOR EACH ROW EXECUTE FUNCTION agent_records_append_only()"
        )
        op.execute(
            "CREATE TRIGGER agent_records_no_truncate BEFORE TRUNCATE ON agent_records "
            "FOR EACH STATEMENT EXECUTE FUNCTION agent_records_append_only()"
        )
        for table, privileges in _GRANTS.items():
            op.execute(f"REVOKE ALL ON {table} FROM PUBLIC")
            op.execute(f"GRANT {privileges} ON {table} TO {RUNNER_ROLE}")
        for table in ("agent_proposals", "agent_records"):
            op.execute(f"GRANT USAGE ON SEQUENCE {table}_id_seq TO {RUNNER_ROLE}")
    else:
        for operation in ("UPDATE", "DELETE"):
            op.execute(
                f"CREATE TRIGGER agent_records_no_{operation.lower()} BEFORE {operation} ON agent_records "
                "BEGIN SELECT RAISE(ABORT, 'agent records are append-only'); END"
            )


def downgrade() -> None:
    raise NotImplementedError("the audit log is never downgraded: restore a backup instead")
