"""Tamper evidence: a hash chain per run, append-only triggers, and (PostgreSQL) the runner's grants.

Existing events are linked in sequence order, run by run, exactly as new ones are
(:mod:`records.audit_chain`), so an upgraded log verifies like a new one. Triggers then refuse
UPDATE and DELETE (and TRUNCATE on PostgreSQL) for everyone, the owner included; on PostgreSQL
the group role ``caretaker_runner`` may SELECT and INSERT events and nothing else.

Revision ID: 0002
Revises: 0001
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from records.audit_chain import GENESIS, link_hash
from records.audit_schema import RUNNER_ROLE, VERSION_TABLE

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None

_BATCH = 1000


def upgrade() -> None:
    op.add_column("audit_records", sa.Column("prev_hash", sa.String(64), nullable=True))
    op.add_column("audit_records", sa.Column("hash", sa.String(64), nullable=True))
    _link_existing_events()
    with op.batch_alter_table("audit_records") as batch:
        batch.alter_column("prev_hash", existing_type=sa.String(64), nullable=False)
        batch.alter_column("hash", existing_type=sa.String(64), nullable=False)
    if op.get_bind().dialect.name == "postgresql":
        _postgresql_append_only()
    else:
        for operation in ("UPDATE", "DELETE"):
            op.execute(
                f"CREATE TRIGGER audit_records_no_{operation.lower()} BEFORE {operation} ON audit_records "
                "BEGIN SELECT RAISE(ABORT, 'audit records are append-only'); END"
            )


def _link_existing_events() -> None:
    records = sa.table(
        "audit_records",
        sa.column("time", sa.DateTime(timezone=True)),
        *(
            sa.column(name)
            for name in ("id", "run_id", "seq", "actor", "kind", "instruction", "data", "prev_hash", "hash")
        ),
    )
    bind = op.get_bind()
    rows = bind.execute(
        sa.select(
            records.c.id,
            records.c.run_id,
            records.c.seq,
            records.c.time,
            records.c.actor,
            records.c.kind,
            records.c.instruction,
            records.c.data,
        ).order_by(records.c.run_id, records.c.seq)
    ).all()
    update = (
        records.update()
        .where(records.c.id == sa.bindparam("row_id"))
        .values(prev_hash=sa.bindparam("new_prev"), hash=sa.bindparam("new_hash"))
    )
    batch: list[dict[str, object]] = []
    run, prev = None, GENESIS
    for row in rows:
        if row.run_id != run:
            run, prev = row.run_id, GENESIS
        new_hash = link_hash(
            prev,
            run_id=row.run_id,
            seq=row.seq,
            time=row.time,
            actor=row.actor,
            kind=row.kind,
            instruction=row.instruction,
            data=row.data,
        )
        batch.append({"row_id": row.id, "new_prev": prev, "new_hash": new_hash})
        prev = new_hash
        if len(batch) >= _BATCH:
            bind.execute(update, batch)
            batch = []
    if batch:
        bind.execute(update, batch)


def _postgresql_append_only() -> None:
    bind = op.get_bind()
    if bind.exec_driver_sql(f"SELECT 1 FROM pg_roles WHERE rolname = '{RUNNER_ROLE}'").first() is None:
        may_create = bind.exec_driver_sql(
            "SELECT rolsuper OR rolcreaterole FROM pg_roles WHERE rolname = current_user"
        ).scalar()
        if not may_create:
            raise RuntimeError(
                f"role {RUNNER_ROLE} does not exist and {bind.engine.url.username} may not create it: "
                f"a database administrator runs CREATE ROLE {RUNNER_ROLE} NOLOGIN "
                "(docs/ground-segment.md), then the upgrade again"
            )
        op.execute(f"CREATE ROLE {RUNNER_ROLE} NOLOGIN")
    op.execute("""
        CREATE FUNCTION audit_records_append_only() RETURNS trigger LANGUAGE plpgsql AS $$
        BEGIN
            RAISE EXCEPTION 'audit records are append-only (% refused)', TG_OP USING ERRCODE = 'insufficient_privilege';
        END $$""")
    op.execute(
        "CREATE TRIGGER audit_records_append_only BEFORE UPDATE OR DELETE ON audit_records "
        "FOR EACH ROW EXECUTE FUNCTION audit_records_append_only()"
    )
    op.execute(
        "CREATE TRIGGER audit_records_no_truncate BEFORE TRUNCATE ON audit_records "
        "FOR EACH STATEMENT EXECUTE FUNCTION audit_records_append_only()"
    )
    op.execute("REVOKE ALL ON audit_records FROM PUBLIC")
    op.execute(f"GRANT SELECT, INSERT ON audit_records TO {RUNNER_ROLE}")
    op.execute(f"GRANT USAGE ON SEQUENCE audit_records_id_seq TO {RUNNER_ROLE}")
    op.execute(f"GRANT SELECT ON {VERSION_TABLE} TO {RUNNER_ROLE}")


def downgrade() -> None:
    raise NotImplementedError("the audit log is never downgraded: restore a backup instead")
