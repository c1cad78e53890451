"""Schema version 2: an index on runs.status (the report reads the finished runs, the grid
the running and finished runs of a cell, by status), and store_info always present,
holding schema_version "2" (stores made before commit e14c752 have no store_info).

Revision ID: 0002
Revises: 0001
"""

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None

# store_info as this revision knows it (a script keeps its own copy of what it touches, so a
# later change of schema.py cannot change what this step does)
_store_info = sa.table("store_info", sa.column("key", sa.String), sa.column("value", sa.String))


def _record_version(version: int) -> None:
    op.execute(_store_info.delete().where(_store_info.c.key == "schema_version"))
    op.execute(_store_info.insert().values(key="schema_version", value=str(version)))


def upgrade() -> None:
    op.create_index("ix_runs_status", "runs", ["status"])
    if not sa.inspect(op.get_bind()).has_table("store_info"):
        op.create_table(
            "store_info",
            sa.Column("key", sa.String(40), primary_key=True),
            sa.Column("value", sa.String(200), nullable=False),
        )
    _record_version(2)


def downgrade() -> None:
    op.drop_index("ix_runs_status", table_name="runs")
    _record_version(1)
