"""Every ``CROSSROADS_*`` environment variable is read in settings.py, and each means what it says."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from crossroads import settings
from support import REPO_ROOT

PACKAGE = REPO_ROOT / "backend" / "crossroads"
SETTINGS = PACKAGE / "settings.py"
VARIABLE = re.compile(r"CROSSROADS_[A-Z0-9_]*")


def _variable_names(path: Path) -> list[str]:
    """String constants of ``path`` that are a CROSSROADS_ variable's name (or its prefix)."""
    names = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and VARIABLE.fullmatch(node.value):
            names.append(node.value)
    return names


def test_no_module_but_settings_names_a_crossroads_variable() -> None:
    found = {str(p.relative_to(PACKAGE)): names for p in PACKAGE.rglob("*.py")
             if p != SETTINGS and (names := _variable_names(p))}
    assert found == {}, "read these through crossroads.settings"
    assert _variable_names(SETTINGS) == ["CROSSROADS_"]  # the one prefix, for Settings and the library


def test_the_library_variables(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    for name in ("CACHE_DIR", "SCENARIOS_DIR", "FRONTEND_DIST", "FORK_EPISODES"):
        monkeypatch.delenv(f"CROSSROADS_{name}", raising=False)
    assert settings.net_cache_dir() == Path.home() / ".cache" / "crossroads" / "nets"
    assert settings.scenarios_dir() == REPO_ROOT / "scenarios"
    assert settings.frontend_dist_dir() == REPO_ROOT / "frontend" / "dist"
    assert settings.fork_episodes()
    monkeypatch.setenv("CROSSROADS_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("CROSSROADS_SCENARIOS_DIR", str(tmp_path / "scenarios"))
    monkeypatch.setenv("CROSSROADS_FRONTEND_DIST", str(tmp_path / "dist"))
    monkeypatch.setenv("CROSSROADS_FORK_EPISODES", "0")
    assert settings.net_cache_dir() == tmp_path / "cache"
    assert settings.scenarios_dir() == tmp_path / "scenarios"
    assert settings.frontend_dist_dir() == tmp_path / "dist"
    assert not settings.fork_episodes()

