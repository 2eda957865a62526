"""Oriented-rectangle overlap (separating axes) against shapely's polygons."""

from __future__ import annotations

import math

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


def _overlapping_arrays(ego, x, y, heading, length, width, margin_m=0.0):
    """The separating-axis test on arrays for every rectangle (overlapping() without its float path)."""
    ex, ey, eh, el, ew = ego
    dx, dy = x - ex, y - ey
    half_el, half_ew = el / 2.0 + margin_m, ew / 2.0 + margin_m
    hl, hw = length / 2.0 + margin_m, width / 2.0 + margin_m
    near = np.hypot(dx, dy) <= np.hypot(half_el, half_ew) + np.hypot(hl, hw)
    ce, se = np.cos(eh), np.sin(eh)
    co, so = np.cos(heading), np.sin(heading)
    separated = np.zeros(len(dx), dtype=bool)
    for ax, ay, half_e in ((ce, se, half_el), (-se, ce, half_ew)):
        separated |= np.abs(dx * ax + dy * ay) > half_e + hl * np.abs(co * ax + so * ay) + hw * np.abs(-so * ax + co * ay)
    for ax, ay, half_o in ((co, so, hl), (-so, co, hw)):
        separated |= np.abs(dx * ax + dy * ay) > half_o + half_el * np.abs(ce * ax + se * ay) + half_ew * np.abs(-se * ax + ce * ay)
    return near & ~separated


def test_float_path_and_array_path_agree() -> None:
    """A few near rectangles are tested one by one on floats, many on arrays: the same answers,
    including the touching cases where rounding decides."""
    rng = np.random.default_rng(3)
    for _ in range(300):
        n = int(rng.integers(1, 12))
        ego = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), float(rng.uniform(-np.pi, np.pi)), 4.8, 1.8)
        x, y = rng.uniform(-6, 6, n), rng.uniform(-6, 6, n)
        h, length, width = rng.uniform(-np.pi, np.pi, n), rng.uniform(0.3, 6, n), rng.uniform(0.3, 3, n)
        if rng.random() < 0.3:  # exactly touching side by side
            x[0], y[0], h[0], length[0], width[0] = ego[0], ego[1] + 1.8, ego[2], 4.8, 1.8
        margin = float(rng.choice([0.0, 0.2]))
        expected = _overlapping_arrays(ego, x, y, h, length, width, margin)
        np.testing.assert_array_equal(overlapping(ego, x, y, h, length, width, margin), expected)
        for k in range(n):  # one at a time: always the float path
            got = overlapping(ego, x[k:k + 1], y[k:k + 1], h[k:k + 1], length[k:k + 1], width[k:k + 1], margin)
            assert bool(got[0]) == bool(expected[k])


def test_corners_are_the_vector_formula_and_math_trig_is_numpy_trig() -> None:
    """The float fast paths (corners here, x_track in idc.state, the front-vehicle check) use
    math.cos/sin where the array code used numpy's: bit for bit the same on this platform."""
    rng = np.random.default_rng(4)
    angles = np.concatenate([rng.uniform(-4, 4, 20000), rng.uniform(-1e3, 1e3, 2000)])
    assert np.cos(angles).tolist() == [math.cos(a) for a in angles.tolist()]
    assert np.sin(angles).tolist() == [math.sin(a) for a in angles.tolist()]
    for x, y, h, length, width in rng.uniform(-50, 50, (200, 5)):
        c, s = np.cos(h), np.sin(h)
        forward, left, centre = np.array([c, s]) * (length / 2.0), np.array([-s, c]) * (width / 2.0), np.array([x, y])
        expected = np.array([centre + forward + left, centre - forward + left,
                             centre - forward - left, centre + forward - left])
        assert rectangle_corners(x, y, h, length, width).tobytes() == expected.tobytes()
