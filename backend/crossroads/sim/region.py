"""Point-in-polygon tests the outcome judge makes every step, answered from a memo of grid cells.

The judge asks after every step whether the ego's four corners lie in the drivable area (and, past
the stop line, whether its centre is in the target exit and its corners out of the junction).
GEOS answers each question in a few microseconds, several times that in the control loop where
SUMO's step has just pushed its index out of the caches. Most of the time the corners are far
from any edge: a grid cell whose box, grown by a margin, lies in the polygon's interior answers
"inside" for every point in it, one entirely apart from the polygon answers "outside", and those
are exactly GEOS's answers (its predicates are exact, and so is the cell of a point: x / 2^k).
Only points in cells the boundary crosses go to GEOS. Cells are classified on first use and
remembered (an episode visits a few hundred; the next episodes of the world reuse them).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import shapely
from shapely.geometry.base import BaseGeometry

CELL_M = 1.0  # [m] side of a grid cell (a power of two: a point's cell is exact)
MARGIN_M = 0.01  # [m] a cell's box is grown by this before it is classified
INSIDE, OUTSIDE, BOUNDARY = 1, -1, 0


class Region:
    """``shapely.contains_xy`` on one polygon, with the same answers, from a memo of grid cells."""

    def __init__(self, geometry: BaseGeometry, cell_m: float = CELL_M, margin_m: float = MARGIN_M) -> None:
        if not (cell_m > 0.0 and math.frexp(cell_m)[0] == 0.5):
            raise ValueError(f"cell_m must be a power of two, got {cell_m}")
        self.geometry = geometry
        shapely.prepare(geometry)
        self._cell = cell_m
        self._margin = margin_m
        self._cells: dict[tuple[int, int], int] = {}

    def contains(self, x: float, y: float) -> bool:
        """``shapely.contains_xy(geometry, x, y)``."""
        state = self._state(x, y)
        if state != BOUNDARY:
            return state == INSIDE
        return bool(shapely.contains_xy(self.geometry, x, y))

    def contains_all(self, xs: Sequence[float], ys: Sequence[float]) -> bool:
        """``shapely.contains_xy(geometry, xs, ys).all()``."""
        return not self._some(xs, ys, contained=False)

    def contains_any(self, xs: Sequence[float], ys: Sequence[float]) -> bool:
        """``shapely.contains_xy(geometry, xs, ys).any()``."""
        return self._some(xs, ys, contained=True)

    def _some(self, xs: Sequence[float], ys: Sequence[float], contained: bool) -> bool:
        """Whether some point's ``contains_xy`` is ``contained``: the cells answer first (a cell
        that settles it ends the search), GEOS only for the points in boundary cells."""
        settles = INSIDE if contained else OUTSIDE
        unsure = []
        for x, y in zip(xs, ys):
            state = self._state(x, y)
            if state == settles:
                return True
            if state == BOUNDARY:
                unsure.append((x, y))
        return any(bool(shapely.contains_xy(self.geometry, x, y)) == contained for x, y in unsure)

    def _state(self, x: float, y: float) -> int:
        """INSIDE, OUTSIDE or BOUNDARY: what the cell of (x, y) says about it."""
        if not (math.isfinite(x) and math.isfinite(y)):
            return BOUNDARY  # GEOS decides (and no cell holds such a point)
        key = (math.floor(x / self._cell), math.floor(y / self._cell))
        state = self._cells.get(key)
        if state is None:
            state = self._cells[key] = self._classify(*key)
        return state

    def _classify(self, i: int, j: int) -> int:
        c, m = self._cell, self._margin
        box = shapely.box(i * c - m, j * c - m, (i + 1) * c + m, (j + 1) * c + m)
        if shapely.contains_properly(self.geometry, box):
            return INSIDE  # every point of the box is in the interior: contains_xy is True
        if shapely.disjoint(self.geometry, box):
            return OUTSIDE  # no point of the box is in the polygon: contains_xy is False
        return BOUNDARY
