"""Paths and helpers shared by the tests (import as ``from support import ...``)."""

from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("CROSSROADS_SHARED_DIR", REPO_ROOT.parent / "shared"))
REALNETS = SHARED / "realnets"
COLOGNE1_NET = REALNETS / "resco_cologne1" / "cologne1.net.xml"
SUMO_RL_NET = REALNETS / "sumo-rl_2way-single-intersection" / "single-intersection.net.xml"


def sumo_example(relative: str) -> Path:
    """A network shipped with SUMO itself (inside the eclipse-sumo wheel)."""
    import sumo

    return Path(sumo.SUMO_HOME) / relative


SUMO_CROSS_NET = "tools/game/cross/cross.net.xml"
