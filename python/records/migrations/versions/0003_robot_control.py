"""Control of robots in the ground database: one row per controlled robot (:mod:`records.robot_control`).

The primary key on ``robot`` is what makes control exclusive across processes: a second INSERT
for a robot fails. On PostgreSQL the runner's role (``caretaker_runner``) may read and change
the rows: taking, taking over and releasing control are what a runner does.

Revision ID: 0003
Revises: 0002
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from records.audit_schema import RUNNER_ROLE

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "robot_control",
        sa.Column("robot", sa.String(120), primary_key=True),
        sa.Column("run_id", sa.String(120), nullable=False),
        sa.Column("user_id", sa.String(120), nullable=False),
        sa.Column("since", sa.DateTime(timezone=True), nullable=False),
        sa.Column("reason", sa.Text, nullable=False),
    )
    if op.get_bind().dialect.name == "postgresql":
        op.execute("REVOKE ALL ON robot_control FROM PUBLIC")
        op.execute(f"GRANT SELECT, INSERT, UPDATE, DELETE ON robot_control TO {RUNNER_ROLE}")


def downgrade() -> None:
    raise NotImplementedError("the audit log is never downgraded: restore a backup instead")
