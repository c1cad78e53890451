"""Schema version 3: the table verifications (`coadapt verify`, issue 60), one row per
verified design of a run: its improvement over the nominal design with specialist policies
and with the universal policy, each with its standard error, their difference and the
verdict. Nothing else changes; a store upgraded from version 2 keeps every row.

Revision ID: 0003
Revises: 0002
"""

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None

_store_info = sa.table("store_info", sa.column("key", sa.String), sa.column("value", sa.String))


def _record_version(version: int) -> None:
    op.execute(_store_info.delete().where(_store_info.c.key == "schema_version"))
    op.execute(_store_info.insert().values(key="schema_version", value=str(version)))


def upgrade() -> None:
    # the table as this revision knows it (a script keeps its own copy of what it creates)
    op.create_table(
        "verifications",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column(
            "run_id",
            sa.String(80),
            sa.ForeignKey("runs.id", ondelete="CASCADE"),
            nullable=False,
        ),
        sa.Column("key", sa.String(80), nullable=False),
        sa.Column("budget", sa.BigInteger, nullable=False),
        sa.Column("seed", sa.Integer, nullable=False),
        sa.Column("role", sa.String(80), nullable=False),
        sa.Column("design", sa.Text, nullable=False),
        sa.Column("objective", sa.String(80), nullable=False),
        sa.Column("universal_improvement", sa.Float),
        sa.Column("universal_improvement_se", sa.Float),
        sa.Column("specialist_improvement", sa.Float),
        sa.Column("specialist_improvement_se", sa.Float),
        sa.Column("difference", sa.Float),
        sa.Column("difference_se", sa.Float),
        sa.Column("verdict", sa.String(20), nullable=False),
        sa.Column("scenarios", sa.Integer, nullable=False),
        sa.Column("interactions", sa.BigInteger, nullable=False),
        sa.Column("seconds", sa.Float, nullable=False),
        sa.Column("detail", sa.Text),
        sa.Column("created_at", sa.Float, nullable=False),
        sa.UniqueConstraint("run_id", "key", "role", name="uq_verification"),
    )
    _record_version(3)


def downgrade() -> None:
    op.drop_table("verifications")
    _record_version(2)
