"""Oriented-rectangle overlap (separating axes) against shapely's polygons."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon

from crossroads.sim.footprint import overlapping, rectangle_corners

coord = st.floats(-8.0, 8.0)
angle = st.floats(-np.pi, np.pi)
size = st.floats(0.3, 6.0)


@settings(max_examples=300, deadline=None)
@given(coord, coord, angle, size, size, angle, size, size)
def test_overlap_agrees_with_shapely(x, y, h, length, width, eh, el, ew) -> None:
    ego = (0.0, 0.0, eh, el, ew)
    other = Polygon(rectangle_corners(x, y, h, length, width))
    mine = Polygon(rectangle_corners(*ego))
    expected = mine.intersects(other)
    if abs(mine.distance(other)) < 1e-6 and not mine.intersection(other).area > 1e-9:
        return  # touching within rounding: either answer is right
    got = overlapping(ego, np.array([x]), np.array([y]), np.array([h]),
                      np.array([length]), np.array([width]))
    assert bool(got[0]) == expected


def test_empty_and_far() -> None:
    ego = (0.0, 0.0, 0.0, 4.8, 2.0)
    assert overlapping(ego, *(np.zeros(0) for _ in range(5))).shape == (0,)
    far = overlapping(ego, np.array([50.0]), np.array([0.0]), np.array([0.0]),
                      np.array([4.0]), np.array([2.0]))
    assert not far.any()


def test_side_by_side_lanes_do_not_touch() -> None:
    ego = (0.0, 0.0, 0.0, 4.8, 2.0)
    neighbour = overlapping(ego, np.array([1.0]), np.array([3.5]), np.array([0.0]),
                            np.array([4.8]), np.array([2.0]))
    assert not neighbour.any()
