"""Alembic migrations of the results store (applied by :func:`crossroads.store.open_store`)."""
