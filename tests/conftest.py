"""Shared fixtures. Paths to the real SUMO networks written by others (used in place)."""

from __future__ import annotations

import os

import pytest

from support import REPO_ROOT  # noqa: F401  (re-exported for fixtures)


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Network builds go to a per-run cache, so tests never read a stale build from a session."""
    os.environ.setdefault("CROSSROADS_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
