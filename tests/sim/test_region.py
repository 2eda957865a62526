"""The judge's point-in-polygon tests from a memo of grid cells: always shapely's answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from shapely.geometry import Point, Polygon

from crossroads.sim.region import BOUNDARY, INSIDE, OUTSIDE, Region


@pytest.fixture(scope="module")
def shape() -> Polygon:
    # a road-like shape: a cross of two strips with a hole, rounded by a buffer
    cross = shapely.union(shapely.box(-40, -5, 40, 5), shapely.box(-5, -40, 5, 40))
    return cross.difference(Point(20, 0).buffer(2.0)).buffer(0.5)


def test_answers_are_shapelys(shape: Polygon) -> None:
    rng = np.random.default_rng(0)
    region = Region(shape)
    # random points, points on a fine lattice (cell borders) and points hugging the boundary
    boundary = np.array(shape.exterior.coords)
    pts = np.concatenate([rng.uniform(-45, 45, (4000, 2)), np.mgrid[-42:42:0.5, -42:42:0.5].reshape(2, -1).T,
                          boundary + rng.normal(0, 1e-9, boundary.shape), boundary])
    expected = shapely.contains_xy(shape, pts[:, 0], pts[:, 1])
    assert [region.contains(x, y) for x, y in pts.tolist()] == expected.tolist()
    for k in range(0, len(pts) - 4, 4):  # in fours, as the ego's corners
        xs, ys = pts[k:k + 4, 0].tolist(), pts[k:k + 4, 1].tolist()
        assert region.contains_all(xs, ys) == bool(expected[k:k + 4].all())
        assert region.contains_any(xs, ys) == bool(expected[k:k + 4].any())
    states = set(region._cells.values())
    assert states == {INSIDE, OUTSIDE, BOUNDARY}  # every kind of cell was met (and remembered)


def test_odd_input(shape: Polygon) -> None:
    region = Region(shape)
    assert not region.contains(math.nan, 0.0) and not region.contains(math.inf, 1.0)
    assert region.contains_all([0.0, 1.0], [0.0, 1.0]) and not region.contains_all([0.0, math.nan], [0.0, 0.0])
    assert region.contains_all([], []) and not region.contains_any([], [])
    with pytest.raises(ValueError):
        Region(shape, cell_m=0.3)
