"""alembic's environment for the results store: it runs the scripts in `versions/` on the
connection `coadapt_core.results.migrate` opened (and holds locked), inside that connection's
transaction, recording the revision in `coadapt_alembic_version` (optuna's studies, which
may share the database, keep their own revision in `alembic_version`)."""

from alembic import context

from coadapt_core.results.migrate import VERSION_TABLE
from coadapt_core.results.schema import metadata

context.configure(
    connection=context.config.attributes["connection"],
    target_metadata=metadata,
    version_table=VERSION_TABLE,
)
with context.begin_transaction():
    context.run_migrations()
