"""Turn what a user names — a catalogue name, an intersection spec or a SUMO network — into a net.

One place decides what a reference means, so the CLI, the API and scenarios agree.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from crossroads.intersections import catalogue
from crossroads.network.junction import read_junction
from crossroads.network.road import Junction

NET_SUFFIXES = (".net.xml", ".net.xml.gz")
SPEC_SUFFIXES = (".yaml", ".yml")


class NetworkNotFoundError(LookupError):
    """The reference is neither a catalogue name nor an existing spec or network file."""


def is_net_file(ref: str | Path) -> bool:
    return str(ref).endswith(NET_SUFFIXES)


def resolve_net(ref: str | Path) -> Path:
    """A catalogue name, an intersection spec (.yaml) or a SUMO network (.net.xml) → .net.xml path.

    Specs and catalogue entries are built by netconvert (cached by the spec's hash).
    """
    text = str(ref)
    if is_net_file(text):
        path = Path(text)
        if not path.is_file():
            raise NetworkNotFoundError(f"SUMO network {text!r} does not exist")
        return path.resolve()
    if text.endswith(SPEC_SUFFIXES):
        if not Path(text).is_file():
            raise NetworkNotFoundError(f"intersection spec {text!r} does not exist")
        return catalogue.build(Path(text))
    names = catalogue.list_intersections()
    if text not in names:
        raise NetworkNotFoundError(
            f"no intersection {text!r}: give a catalogue name ({', '.join(names)}), "
            "an intersection spec (.yaml) or a SUMO network (.net.xml)"
        )
    return catalogue.build(text)


@lru_cache(maxsize=64)
def _read_cached(net_file: Path, mtime_ns: int, junction_id: str | None) -> Junction:
    return read_junction(net_file, junction_id)


def open_junction(ref: str | Path, junction_id: str | None = None) -> Junction:
    """Resolve ``ref`` and read its junction (cached while the file is unchanged)."""
    net = resolve_net(ref)
    return _read_cached(net, net.stat().st_mtime_ns, junction_id)
