"""MkDocs hook: the architecture page's layer table and the imports that break it, read from the code.

A page that holds ``<!-- layer-table -->`` gets the layers of the ``crossroads`` package, lowest
first, each with the packages it imports today; ``<!-- layer-exceptions -->`` gets every import
(module-level or inside a function) that goes from a lower layer to a higher one or between two
packages of the same layer, or "none". So the page says what the code does, not what it did when
the page was written. The rule itself is :data:`LAYERS`.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path
from typing import Any

TABLE_MARKER = "<!-- layer-table -->"
EXCEPTIONS_MARKER = "<!-- layer-exceptions -->"

# Lowest first. A package may import the packages of lower layers only; the packages of one layer
# do not import each other. A top-level module (constants.py) counts as a package of its own.
LAYERS: tuple[tuple[str, tuple[tuple[str, str], ...]], ...] = (
    ("foundations", (("constants", "the paper's numbers, with units and sections"),
                     ("geometry", "pure geometry: Bezier curves, polylines, frames"),
                     ("arrays", "one maths for numpy and torch"),
                     ("validation", "validation helpers: errors that name the field"),
                     ("settings", "the service's settings and every `CROSSROADS_*` variable"),
                     ("cli_errors", "how the command line reports errors"))),
    ("road network", (("network", "SUMO nets read into junctions: approaches, lanes, crossings"),)),
    ("planning", (("planning", "candidate paths (Bezier) and their speed profiles"),)),
    ("intersections", (("intersections", "intersection specs built into SUMO nets, the catalogue, "
                                         "a name or a net file resolved"),)),
    ("perception", (("perception", "the sensors and their noise"),)),
    ("simulation", (("sim", "the SUMO world (only sim/sumo.py imports libsumo), f_ego, traffic, and "
                            "the control contract: observation, snapshot, outcome"),)),
    ("control", (("idc", "the IDC state, utility, constraints, light logic, rule controller, decision, "
                         "shield; imports no libsumo"),)),
    ("learning", (("rl", "the differentiable model, the networks, APG/DPG training, export"),)),
    ("what a user names", (("scenario", "the scenario format and its checks against a network"),
                           ("policy", "policy references (one grammar) and their identities"))),
    ("store", (("store", "the results database"),)),
    ("evaluation", (("evaluation", "episodes, batches, metrics, reports, controllers by reference"),)),
    ("tools on evaluation", (("gym", "the Gymnasium environment"), ("search", "the search for failures"))),
    ("viewing", (("viz", "the 3D view"),)),
    ("service", (("api", "the HTTP API and the studio page"),)),
    ("command line", (("cli", "the `crossroads` command"),)),
)


def on_page_markdown(markdown: str, config: Any, **_: Any) -> str:
    """Replace the markers (pages without them are returned as they are)."""
    if TABLE_MARKER not in markdown and EXCEPTIONS_MARKER not in markdown:
        return markdown
    package = Path(config["config_file_path"]).parent / "backend" / "crossroads"
    imports = package_imports(package)
    markdown = markdown.replace(TABLE_MARKER, layer_table(imports))
    return markdown.replace(EXCEPTIONS_MARKER, exceptions_list(imports))


def package_imports(package: Path) -> dict[tuple[str, str], set[str]]:
    """(importing package, imported package) → the files of the importer that import it."""
    found: dict[tuple[str, str], set[str]] = defaultdict(set)
    for path in sorted(package.rglob("*.py")):
        rel = path.relative_to(package)
        source = rel.parts[0] if len(rel.parts) > 1 else rel.stem
        for target in _imported(ast.parse(path.read_text(encoding="utf-8")), rel):
            if target != source and target != "__init__":
                found[(source, target)].add(rel.as_posix())
    return found


def _imported(tree: ast.AST, rel: Path) -> set[str]:
    """The crossroads packages a module imports, relative imports resolved."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(rel.parts[:-node.level])
                modules = [".".join(["crossroads", *base, *([node.module] if node.module else [])])]
                if not node.module:
                    modules = [f"{modules[0]}.{alias.name}" for alias in node.names]
            elif node.module == "crossroads":  # from crossroads import settings
                modules = [f"crossroads.{alias.name}" for alias in node.names]
            else:
                modules = [node.module or ""]
        else:
            continue
        names |= {m.split(".")[1] for m in modules if m.startswith("crossroads.") and m.count(".") >= 1}
    return names


def _level(name: str) -> int | None:
    return next((i for i, (_, members) in enumerate(LAYERS) if name in dict(members)), None)


def layer_table(imports: dict[tuple[str, str], set[str]]) -> str:
    """One row per package, lowest layer first, with the crossroads packages it imports today."""
    rows = ["| layer | package | what | imports today |", "|---|---|---|---|"]
    for title, members in LAYERS:
        for member, what in members:
            used = sorted({t for (s, t) in imports if s == member})
            rows.append(f"| {title} | `{member}` | {what} | {', '.join(f'`{u}`' for u in used) or '—'} |")
    placed = {m for _, members in LAYERS for m, _ in members}
    for name in sorted({s for (s, _) in imports} - placed):
        used = sorted({t for (s, t) in imports if s == name})
        rows.append(f"| (not placed) | `{name}` | to be placed in a layer | {', '.join(f'`{u}`' for u in used)} |")
    return "\n".join(rows)


def violations(imports: dict[tuple[str, str], set[str]]) -> list[tuple[str, str, list[str]]]:
    """(importer, imported, files) of every import against the layers: upward, sideways, or from
    or to a package :data:`LAYERS` does not place (``__version__`` of the package root aside)."""
    found = []
    for (source, target), files in sorted(imports.items()):
        if target == "__version__":
            continue
        low, high = _level(source), _level(target)
        if low is None or high is None or high >= low:
            found.append((source, target, sorted(files)))
    return found


def exceptions_list(imports: dict[tuple[str, str], set[str]]) -> str:
    """One line per import against the layers (:func:`violations`), or "none"."""
    lines = [f"- `{source}` → `{target}` ({', '.join(files)})" for source, target, files in violations(imports)]
    return "\n".join(lines) if lines else "None: every import goes from a higher layer to a lower one."
