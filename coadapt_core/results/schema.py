"""The results store's layout: its tables (SQLAlchemy Core), the kinds and statuses its rows
take, and the layout's version.

SCHEMA_VERSION is recorded in the table `store_info` when a store is created and checked
each time one is opened (`coadapt_core.results.migrate.open_schema`). A store made before
the version was recorded has the layout of version 1. An older store is upgraded in place
when it is opened, after a backup copy, by the alembic scripts in `results/migrations/`; a
store of a newer version than this coadapt knows is refused with one line. A change of the
tables raises SCHEMA_VERSION and adds the script of the new version there.
"""

from __future__ import annotations

import sqlalchemy as sa

from coadapt_core import __version__
from coadapt_core.errors import UserError

#: version of the tables below; 1 is the layout every store had before versions were recorded,
#: 2 adds the index on runs.status, 3 the table verifications (migrations/versions/ holds each
#: version's script)
SCHEMA_VERSION = 3
#: the key of the version's row in `store_info`
SCHEMA_VERSION_KEY = "schema_version"

#: evaluation kinds: the loop's two, plus transfer to a second simulator (report) and
#: the grid evaluations of `coadapt landscape` (stored as "real")
EVALUATION_KINDS = ("real", "surrogate", "sim2sim", "common")
#: rows of sim-to-sim transfer (coadapt_core.experiments.transfer): their kind, and the outer
#: index they are stored with (they belong to no iteration of the run)
TRANSFER_KIND, TRANSFER_OUTER = "sim2sim", -1
#: rows of the common yardstick (coadapt_core.experiments.yardstick): their kind and outer index
COMMON_KIND, COMMON_OUTER = "common", -2
#: the method recorded by cost-landscape runs (coadapt_core.experiments.landscape)
LANDSCAPE_METHOD = "landscape"
#: statuses the store and the grid use (the loop may report others; they are kept as given)
RUN_STATUSES = ("running", "finished", "failed", "interrupted")

metadata = sa.MetaData()

runs = sa.Table(
    "runs",
    metadata,
    sa.Column("id", sa.String(80), primary_key=True),
    sa.Column("grid_id", sa.String(80), index=True),
    sa.Column("cell", sa.String(200), index=True),  # grid cell key, see grid.Cell.key
    sa.Column("method", sa.String(40), index=True),
    sa.Column("objectives", sa.String(200)),  # comma list, in cost order
    sa.Column("terrain", sa.String(40)),
    sa.Column("optimizer", sa.String(40)),
    sa.Column("simulator", sa.String(40)),
    sa.Column("robot", sa.String(40)),
    sa.Column("preset", sa.String(40)),
    sa.Column("seed", sa.Integer),
    sa.Column("config", sa.Text),  # JSON, the run's full configuration
    sa.Column("code_version", sa.String(40)),  # coadapt package version
    sa.Column("git_commit", sa.String(60)),  # commit of the source tree, "+dirty" when modified
    sa.Column("status", sa.String(20), nullable=False, index=True),
    sa.Column("run_dir", sa.Text),
    sa.Column("created_at", sa.Float, nullable=False),  # unix seconds
    sa.Column("updated_at", sa.Float, nullable=False),
    sa.Column("finished_at", sa.Float),
    sa.Column("summary", sa.Text),  # JSON, what the run reported at the end
)

evaluations = sa.Table(
    "evaluations",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column(
        "run_id", sa.String(80), sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False
    ),
    sa.Column("outer", sa.Integer, nullable=False),  # outer iteration n of Algorithm 4
    sa.Column("inner", sa.Integer, nullable=False),  # optimizer iteration j within it
    sa.Column("idx", sa.Integer, nullable=False),  # position within the (outer, inner, kind) batch
    sa.Column("kind", sa.String(20), nullable=False),  # real | surrogate | sim2sim
    sa.Column("design", sa.Text, nullable=False),  # JSON list of design variable values
    sa.Column("costs", sa.Text, nullable=False),  # JSON {objective: cost}
    sa.Column("surrogate_error", sa.Text),  # JSON {objective: surrogate - real}, when known
    sa.Column("interactions", sa.BigInteger, nullable=False),
    sa.Column("seconds", sa.Float, nullable=False),
    sa.Column("simulator", sa.String(40)),  # set for sim2sim rows
    sa.Column("created_at", sa.Float, nullable=False),
    sa.UniqueConstraint("run_id", "outer", "inner", "kind", "idx", name="uq_evaluation"),
    sa.Index("ix_evaluations_run", "run_id", "kind"),
)

training_phases = sa.Table(
    "training_phases",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column(
        "run_id", sa.String(80), sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False
    ),
    sa.Column("outer", sa.Integer, nullable=False),
    sa.Column("idx", sa.Integer, nullable=False),  # several phases per outer iteration (BO)
    sa.Column("steps", sa.BigInteger, nullable=False),  # environment interactions
    sa.Column("seconds", sa.Float, nullable=False),
    sa.Column("final_reward", sa.Float),
    sa.Column("extra", sa.Text),  # JSON
    sa.Column("created_at", sa.Float, nullable=False),
    sa.UniqueConstraint("run_id", "outer", "idx", name="uq_training_phase"),
)

checkpoints = sa.Table(
    "checkpoints",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column(
        "run_id", sa.String(80), sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False
    ),
    sa.Column("outer", sa.Integer, nullable=False),
    sa.Column("path", sa.Text, nullable=False),
    sa.Column("created_at", sa.Float, nullable=False),
    sa.UniqueConstraint("run_id", "outer", "path", name="uq_checkpoint"),
)

grids = sa.Table(
    "grids",
    metadata,
    sa.Column("id", sa.String(80), primary_key=True),
    sa.Column("spec", sa.Text, nullable=False),  # JSON GridSpec
    sa.Column("created_at", sa.Float, nullable=False),
    sa.Column("updated_at", sa.Float, nullable=False),
)

grid_cells = sa.Table(
    "grid_cells",
    metadata,
    sa.Column(
        "grid_id", sa.String(80), sa.ForeignKey("grids.id", ondelete="CASCADE"), primary_key=True
    ),
    sa.Column("cell", sa.String(200), primary_key=True),
    sa.Column("run_id", sa.String(80)),
    sa.Column(
        "status", sa.String(20), nullable=False
    ),  # pending | running | finished | failed | skipped
    sa.Column("attempts", sa.Integer, nullable=False, default=0),
    sa.Column("last_error", sa.Text),
    sa.Column("updated_at", sa.Float, nullable=False),
)

#: `coadapt verify` (coadapt_core.coadapt.verify): one row per verified design of a run, its
#: improvement over the nominal design with specialists and with the universal policy
verifications = sa.Table(
    "verifications",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column(
        "run_id", sa.String(80), sa.ForeignKey("runs.id", ondelete="CASCADE"), nullable=False
    ),
    sa.Column("key", sa.String(80), nullable=False),  # budget and seed, verify.verify_key
    sa.Column("budget", sa.BigInteger, nullable=False),  # interactions per specialist
    sa.Column("seed", sa.Integer, nullable=False),
    sa.Column("role", sa.String(80), nullable=False),  # best | chosen | lowest-<objective> | design
    sa.Column("design", sa.Text, nullable=False),  # JSON list
    sa.Column("objective", sa.String(80), nullable=False),  # the first objective
    sa.Column("universal_improvement", sa.Float),
    sa.Column("universal_improvement_se", sa.Float),
    sa.Column("specialist_improvement", sa.Float),
    sa.Column("specialist_improvement_se", sa.Float),
    sa.Column("difference", sa.Float),  # specialist - universal
    sa.Column("difference_se", sa.Float),
    sa.Column("verdict", sa.String(20), nullable=False),  # holds | grows | shrinks | does not hold
    sa.Column("scenarios", sa.Integer, nullable=False),
    sa.Column("interactions", sa.BigInteger, nullable=False),  # training + evaluation
    sa.Column("seconds", sa.Float, nullable=False),
    sa.Column("detail", sa.Text),  # JSON: both sides (plain means, fall rates), the verdict line
    sa.Column("created_at", sa.Float, nullable=False),
    sa.UniqueConstraint("run_id", "key", "role", name="uq_verification"),
)

#: one row per fact about the store itself; "schema_version" is the layout's version
store_info = sa.Table(
    "store_info",
    metadata,
    sa.Column("key", sa.String(40), primary_key=True),
    sa.Column("value", sa.String(200), nullable=False),
)

TABLES = (
    "runs",
    "evaluations",
    "training_phases",
    "checkpoints",
    "grids",
    "grid_cells",
    "verifications",
)


def recorded_version(conn: sa.Connection) -> int | None:
    """The schema version a store records, or None when it records none (a store made
    before versions were recorded, or an empty database)."""
    if not sa.inspect(conn).has_table(store_info.name):
        return None
    value = conn.execute(
        sa.select(store_info.c.value).where(store_info.c.key == SCHEMA_VERSION_KEY)
    ).scalar_one_or_none()
    if value is None:
        return None
    try:
        return int(value)
    except ValueError:
        return -1  # not a number: nothing this coadapt wrote


def check_version(version: int, url: str) -> None:
    """A one-line `UserError` for a version this coadapt does not know (newer, or not a
    number: -1 from `recorded_version`)."""
    if not 1 <= version <= SCHEMA_VERSION:
        shown = version if version > 0 else "unreadable"
        raise UserError(
            f"store '{url}' has schema version {shown}; coadapt {__version__} reads versions 1 to "
            f"{SCHEMA_VERSION}: upgrade coadapt or use another store",
            field="store",
        )
