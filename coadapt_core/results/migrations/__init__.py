"""The results store's migration scripts, run by alembic (`coadapt_core.results.migrate`):
`env.py` hands alembic the store's open connection, `versions/` holds one script per schema
version. They ship inside the package, so an installed coadapt can upgrade a store."""
