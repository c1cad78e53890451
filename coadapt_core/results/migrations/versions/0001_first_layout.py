"""Schema version 1: the layout every store had from the first results store (commit 469704a)
to this revision's successor. Tables runs, evaluations, training_phases, checkpoints, grids
and grid_cells; from commit e14c752 on also store_info, holding schema_version "1" (a store
made before it has no store_info and is version 1 too).

The baseline: a version-1 store is stamped with this revision and nothing in it changes.

Revision ID: 0001
Revises: (none)
"""

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Nothing to change: version-1 stores were made with this layout."""


def downgrade() -> None:
    """Nothing below the first layout."""
