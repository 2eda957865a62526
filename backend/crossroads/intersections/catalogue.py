"""The catalogue of intersections: the YAML specs under ``scenarios/intersections/``.

The paper's six intersections (Fig. 2 (a)-(f)) ship with the repository; users may add more.
The directory is ``$CROSSROADS_SCENARIOS_DIR/intersections`` when that variable is set, else
``<repository root>/scenarios/intersections`` (:func:`crossroads.settings.scenarios_dir`).
"""

from __future__ import annotations

import os
from pathlib import Path

from crossroads.intersections.build import build_network
from crossroads.intersections.spec import IntersectionSpec
from crossroads.settings import scenarios_dir
from crossroads.validation import load_yaml_model

SUFFIXES = (".yaml", ".yml")


class UnknownIntersectionError(KeyError):
    """No catalogued intersection has this name; the message lists the known ones."""

    def __str__(self) -> str:  # KeyError would print the message quoted
        return str(self.args[0])


def intersections_dir() -> Path:
    """Directory holding the intersection specs (``*.yaml``)."""
    return scenarios_dir() / "intersections"


def list_intersections() -> list[str]:
    """Names (file stems) of the catalogued intersections, sorted."""
    folder = intersections_dir()
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.iterdir() if p.suffix in SUFFIXES and p.is_file())


def spec_path(name_or_path: str | Path) -> Path:
    """The YAML file of a catalogued name (``"f_irregular_wide"``) or an explicit path.

    A value containing a path separator or a YAML suffix is taken as a path; anything else as a
    name; an unknown name raises :class:`UnknownIntersectionError` listing the known ones.
    """
    text = str(name_or_path)
    if isinstance(name_or_path, Path) or os.sep in text or "/" in text or text.endswith(SUFFIXES):
        return Path(name_or_path)
    for suffix in SUFFIXES:
        candidate = intersections_dir() / f"{text}{suffix}"
        if candidate.is_file():
            return candidate
    known = ", ".join(list_intersections()) or "none"
    raise UnknownIntersectionError(f"unknown intersection {text!r} (in {intersections_dir()}); known: {known}")


def load_spec(name_or_path: str | Path) -> IntersectionSpec:
    """Load and validate an intersection spec; problems raise :class:`crossroads.validation.SpecError`."""
    return load_yaml_model(spec_path(name_or_path), IntersectionSpec)


def build(name_or_path: str | Path) -> Path:
    """The ``.net.xml`` of an intersection, built by netconvert or taken from the cache."""
    return build_network(load_spec(name_or_path))
