"""What a proposal cited and the run it started: ``agent_proposals.cited`` and ``agent_proposals.run_id``.

Revision 0007 creates the agent tables from their one definition (:mod:`records.agent_tables`),
which now holds these columns too: a database made at 0007 after they were added has them already,
one made before lacks them. So each is added only where it is missing.

Revision ID: 0008
Revises: 0007
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0008"
down_revision = "0007"
branch_labels = None
depends_on = None


def upgrade() -> None:
    present = {column["name"] for column in sa.inspect(op.get_bind()).get_columns("agent_proposals")}
    if "cited" not in present:
        op.add_column("agent_proposals", sa.Column("cited", sa.Text, nullable=True))
    if "run_id" not in present:
        op.add_column("agent_proposals", sa.Column("run_id", sa.String(120), nullable=True))


def downgrade() -> None:
    raise NotImplementedError("the audit log is never downgraded: restore a backup instead")
