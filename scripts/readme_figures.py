"""Draws the six catalogue intersections with every candidate path (README, like the paper's Fig. 2).

    .venv/bin/python scripts/readme_figures.py docs/figures
"""

from __future__ import annotations

import sys
from pathlib import Path

from crossroads.intersections import catalogue
from crossroads.intersections.resolve import open_junction
from crossroads.planning import plan_candidates
from crossroads.viz.figure import save_intersection_figure


def main(out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    for name in catalogue.list_intersections():
        junction = open_junction(name)
        candidates = [c for task in ("left", "straight", "right")
                      for c in plan_candidates(junction, task)]
        path = save_intersection_figure(junction, candidates, out_dir / f"{name}.png",
                                        title=name, dpi=80)
        print(path)


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/figures"))
