"""One alembic script per schema version of the results store: revision "0001" is schema
version 1, "0002" version 2, and so on (`coadapt_core.results.migrate.REVISIONS`)."""
