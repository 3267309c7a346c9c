"""Released procedures: the history of each procedure's versions (:mod:`records.releases`).

``procedure_releases`` holds, per procedure id, who saved a version on the Author page, who asked
for a version's release and who released it, each with the version's sha256 (a released row also
with the text and its release number). Rows are only added: a release is never changed, only
followed by another. On PostgreSQL the runner role (the consoles, ``caretaker run``) may read and
add rows, nothing else.

Revision ID: 0005
Revises: 0004
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from records.audit_schema import RUNNER_ROLE

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "procedure_releases",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("procedure", sa.String(120), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("user_id", sa.String(64), nullable=False),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("release", sa.Integer, nullable=True),
        sa.Column("path", sa.Text, nullable=False),
        sa.Column("content", sa.Text, nullable=True),
    )
    op.create_index("ix_procedure_releases_procedure", "procedure_releases", ["procedure"])
    if op.get_bind().dialect.name == "postgresql":
        op.execute("REVOKE ALL ON procedure_releases FROM PUBLIC")
        op.execute(f"GRANT SELECT, INSERT ON procedure_releases TO {RUNNER_ROLE}")
        op.execute(f"GRANT USAGE ON SEQUENCE procedure_releases_id_seq TO {RUNNER_ROLE}")


def downgrade() -> None:
    raise NotImplementedError("the audit log is never downgraded: restore a backup instead")
