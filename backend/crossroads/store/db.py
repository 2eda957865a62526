"""Opening the results store: an engine, its migrations, and sessions.

``open_store(url)`` is the one way in: it creates the engine (SQLite with WAL and foreign keys on,
or PostgreSQL through psycopg 3), applies every Alembic migration (``upgrade head``) and returns a
:class:`Store` that hands out sessions. Callers own their sessions (``with store.session() as s``)
and pass them to the keyword-only helpers of :mod:`crossroads.store.crud`.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Engine, create_engine, event
from sqlalchemy.engine import make_url
from sqlalchemy.orm import Session, sessionmaker

PACKAGE_DIR = Path(__file__).resolve().parent
ALEMBIC_INI = PACKAGE_DIR / "alembic.ini"
MIGRATIONS_DIR = PACKAGE_DIR / "migrations"
SQLITE_BUSY_TIMEOUT_MS = 30_000  # [ms] a writer waits this long for another's lock


class StoreError(RuntimeError):
    """The store cannot be opened (bad URL, unreachable server, failed migration)."""


def default_url() -> str:
    """The URL of the default settings (CROSSROADS_DB_URL, else SQLite in the data dir)."""
    from crossroads.settings import Settings

    return Settings().database_url


def normalize_url(url: str) -> str:
    """``postgresql://`` → ``postgresql+psycopg://`` (psycopg 3 is the driver we ship)."""
    parsed = make_url(url)
    if parsed.drivername in ("postgresql", "postgres"):
        parsed = parsed.set(drivername="postgresql+psycopg")
    return parsed.render_as_string(hide_password=False)


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    try:
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute(f"PRAGMA busy_timeout={SQLITE_BUSY_TIMEOUT_MS}")
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute("PRAGMA synchronous=NORMAL")  # with WAL: commits survive a crash of the app
    finally:
        cursor.close()


def create_store_engine(url: str, **kwargs: Any) -> Engine:
    """An engine for ``url``: SQLite files get WAL + foreign keys (their directory is created)."""
    url = normalize_url(url)
    parsed = make_url(url)
    if parsed.get_backend_name() == "sqlite":
        database = parsed.database
        if database and database != ":memory:" and not database.startswith("file:"):
            Path(database).expanduser().parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(url, **kwargs)
        event.listen(engine, "connect", _sqlite_pragmas)
        return engine
    return create_engine(url, pool_pre_ping=True, **kwargs)


def alembic_config(connection: Any | None = None) -> Config:
    """The Alembic config of the store (from the packaged alembic.ini), bound to ``connection``."""
    config = Config(str(ALEMBIC_INI)) if ALEMBIC_INI.is_file() else Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    if connection is not None:
        config.attributes["connection"] = connection
    return config


def head_revision() -> str | None:
    return ScriptDirectory.from_config(alembic_config()).get_current_head()


class Store:
    """An opened, migrated results store."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self._sessions = sessionmaker(engine, expire_on_commit=False)

    @property
    def url(self) -> str:
        return self.engine.url.render_as_string(hide_password=True)

    @property
    def dialect(self) -> str:
        return self.engine.dialect.name

    def session(self) -> Session:
        """A new session (use as a context manager; commit through the crud helpers)."""
        return self._sessions()

    @contextmanager
    def transaction(self) -> Iterator[Session]:
        """A session in one transaction: committed at the end, rolled back on an exception."""
        with self._sessions.begin() as session:
            yield session

    def revision(self) -> str | None:
        """The migration revision the database is at."""
        with self.engine.connect() as conn:
            return MigrationContext.configure(conn).get_current_revision()

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Store({self.url!r})"


def upgrade(engine: Engine, revision: str = "head") -> None:
    """Apply the migrations up to ``revision`` on ``engine``'s database."""
    with engine.begin() as connection:
        command.upgrade(alembic_config(connection), revision)


def open_store(url: str | None = None, *, migrate: bool = True, **engine_kwargs: Any) -> Store:
    """Open (and by default migrate to head) the store at ``url`` (default: the settings' URL).

    Raises :class:`StoreError` naming the URL (password hidden) when it cannot.
    """
    url = url or default_url()
    try:
        engine = create_store_engine(url, **engine_kwargs)
    except Exception as exc:  # bad URL, missing driver
        raise StoreError(f"cannot open the store {url!r}: {exc}") from exc
    try:
        if migrate:
            upgrade(engine)
    except Exception as exc:
        shown = engine.url.render_as_string(hide_password=True)
        engine.dispose()
        raise StoreError(f"cannot open the store {shown}: {type(exc).__name__}: {exc}") from exc
    return Store(engine)
