"""Alembic environment: migrates the connection open_store() hands over, or the URL of
``-x url=...`` / the default settings when run by hand."""

from __future__ import annotations

from alembic import context
from sqlalchemy import Connection

from crossroads.store.tables import Base

config = context.config
target_metadata = Base.metadata


def _migrate(connection: Connection) -> None:
    context.configure(
        connection=connection,
        target_metadata=target_metadata,
        render_as_batch=connection.dialect.name == "sqlite",  # ALTER TABLE on SQLite
        compare_type=True,
    )
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    connection = config.attributes.get("connection")
    if connection is not None:  # from open_store()
        _migrate(connection)
        return
    from crossroads.store.db import create_store_engine, default_url

    url = context.get_x_argument(as_dictionary=True).get("url") or default_url()
    engine = create_store_engine(url)
    try:
        with engine.connect() as conn:
            _migrate(conn)
    finally:
        engine.dispose()


if context.is_offline_mode():
    raise SystemExit("offline (--sql) migrations are not supported; give a database URL")
run_migrations_online()
