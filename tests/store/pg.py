"""The real PostgreSQL of the tests (127.0.0.1:5432 unless CROSSROADS_TEST_PG says otherwise): a
uniquely named database per use, dropped after. Shared by the store's and the API's tests."""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest

PG_SERVER = os.environ.get("CROSSROADS_TEST_PG", "postgresql+psycopg://postgres@127.0.0.1:5432")


def admin_connect() -> Any:
    import psycopg

    dsn = PG_SERVER.replace("postgresql+psycopg://", "postgresql://") + "/postgres"
    try:
        return psycopg.connect(dsn, autocommit=True, connect_timeout=5)
    except psycopg.OperationalError as exc:
        pytest.fail(f"PostgreSQL is not reachable at {PG_SERVER} ({exc}). The store tests need it: "
                    "start it (e.g. `.ci/run/scripts/setup.sh --test`) and run them again.",
                    pytrace=False)


@contextmanager
def fresh_pg_database() -> Iterator[str]:
    """The URL of a new, uniquely named database on the PostgreSQL server, dropped at the end."""
    name = f"crossroads_test_{uuid.uuid4().hex[:12]}"
    with admin_connect() as conn:
        conn.execute(f'CREATE DATABASE "{name}"')
    try:
        yield f"{PG_SERVER}/{name}"
    finally:
        with admin_connect() as conn:
            conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
