"""Imports flow one way: no module of ``crossroads`` imports a package of its own layer or a higher one.

The layer order is declared once, in ``docs/hooks/import_layers.py`` (``LAYERS``, lowest first),
the hook that also draws the table of docs/guide/architecture.md from the code. This test reads the
import graph of backend/crossroads with ``ast`` through the same functions (every ``import`` and
``from ... import``, at module level or inside a function, relative ones resolved) and fails on any
import against the order, on a package the order does not place, and on a placed name that is no
longer a package.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

from support import REPO_ROOT

PACKAGE = REPO_ROOT / "backend" / "crossroads"


@pytest.fixture(scope="module")
def hook() -> ModuleType:
    spec = importlib.util.spec_from_file_location("import_layers", REPO_ROOT / "docs" / "hooks" / "import_layers.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_no_import_goes_against_the_layers(hook: ModuleType) -> None:
    imports = hook.package_imports(PACKAGE)
    assert len(imports) > 50, "the import graph came out nearly empty: has the reader broken?"
    against = [f"{source} → {target} ({', '.join(files)})" for source, target, files in hook.violations(imports)]
    assert not against, "imports against the layer order (docs/hooks/import_layers.py LAYERS):\n" + "\n".join(against)


def test_every_package_is_placed_and_every_placed_name_exists(hook: ModuleType) -> None:
    packages = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").is_file()}
    modules = {p.stem for p in PACKAGE.glob("*.py") if p.stem != "__init__"}
    placed = [member for _, members in hook.LAYERS for member, _ in members]
    assert len(placed) == len(set(placed)), "a package is placed in two layers"
    assert sorted((packages | modules) - set(placed)) == [], "packages no layer places"
    assert sorted(set(placed) - (packages | modules)) == [], "layers name packages that do not exist"


def _tree(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root


def test_the_reader_catches_upward_sideways_and_relative_imports(hook: ModuleType, tmp_path: Path) -> None:
    """The check can fail: a small tree with one import of each kind against the order."""
    root = _tree(tmp_path / "crossroads", {
        "network/__init__.py": "",
        "network/reads.py": "def f():\n    from crossroads.planning.routes import x  # upward, inside a function\n",
        "planning/__init__.py": "",
        "planning/routes.py": "from ..network import reads  # downward, relative\n",
        "scenario/__init__.py": "",
        "scenario/spec.py": "import crossroads.policy.ref  # sideways: the same layer\n",
        "policy/__init__.py": "",
        "policy/ref.py": "from crossroads import settings  # downward\n",
        "settings.py": "",
    })
    imports = hook.package_imports(root)
    assert imports[("planning", "network")] == {"planning/routes.py"}
    assert [(s, t) for s, t, _ in hook.violations(imports)] == [("network", "planning"), ("scenario", "policy")]
