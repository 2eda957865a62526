"""True footprints: oriented rectangles and their overlap (separating axis theorem), vectorised.

Used to judge collisions on the participants' real poses and sizes, never on the noisy ones.
"""

from __future__ import annotations

import math

import numpy as np

from crossroads.geometry import FloatArray


def rectangle_corners(x: float, y: float, heading: float, length: float, width: float) -> FloatArray:
    """The four corners (4, 2) of a rectangle centred at (x, y) [m], long axis along ``heading``."""
    xs, ys = corner_coordinates(x, y, heading, length, width)
    return np.array(list(zip(xs, ys)))


def corner_coordinates(x: float, y: float, heading: float, length: float,
                       width: float) -> tuple[list[float], list[float]]:
    """The x and the y of :func:`rectangle_corners` (front left, rear left, rear right, front
    right), as Python floats: the judge tests the ego's corners every step on floats."""
    # the arithmetic the (2,)-vector version did, element by element (same numbers; math.cos/sin
    # give numpy's float64 cos/sin, checked in tests/sim/test_footprint.py)
    x, y, heading = float(x), float(y), float(heading)
    c, s = math.cos(heading), math.sin(heading)
    half_l, half_w = length / 2.0, width / 2.0
    fx, fy = c * half_l, s * half_l  # forward
    lx, ly = -s * half_w, c * half_w  # left
    return ([x + fx + lx, x - fx + lx, x - fx - lx, x + fx - lx],
            [y + fy + ly, y - fy + ly, y - fy - ly, y + fy - ly])


def reach(length: FloatArray, width: FloatArray, margin_m: float = 0.0) -> FloatArray:
    """Half diagonal [m] of each rectangle grown by ``margin_m`` (the cheap reject of
    :func:`overlapping`; depends on the sizes only, so the world keeps it while they last)."""
    return np.hypot(length / 2.0 + margin_m, width / 2.0 + margin_m)


def reject_distance(ego_length: float, ego_width: float, others_reach: FloatArray,
                    margin_m: float = 0.0) -> FloatArray:
    """Centre distance [m] beyond which a rectangle cannot overlap the ego's (sum of half diagonals)."""
    return np.hypot(ego_length / 2.0 + margin_m, ego_width / 2.0 + margin_m) + others_reach


SCALAR_ROWS = 4  # overlapping() tests at most this many near rectangles one by one on floats


def overlapping(
    ego: tuple[float, float, float, float, float],
    x: FloatArray, y: FloatArray, heading: FloatArray, length: FloatArray, width: FloatArray,
    margin_m: float = 0.0,
) -> FloatArray:
    """Boolean mask: which of the n rectangles overlap the ego's rectangle ``(x, y, φ, L, W)``.

    Separating axis theorem for two oriented rectangles: they are disjoint iff their projections
    separate on one of the four axes (each rectangle's two edge directions). ``margin_m`` grows
    every rectangle by that much on each side (0: touching counts, as in a real crash).
    """
    ex, ey, eh, el, ew = ego
    n = len(x)
    if n == 0:
        return np.zeros(0, dtype=bool)
    dx, dy = x - ex, y - ey
    half_el, half_ew = el / 2.0 + margin_m, ew / 2.0 + margin_m
    half_l, half_w = length / 2.0 + margin_m, width / 2.0 + margin_m
    # cheap reject: further apart than the sum of the half diagonals
    near = np.hypot(dx, dy) <= reject_distance(el, ew, reach(length, width, margin_m), margin_m)
    result = np.zeros(n, dtype=bool)
    if not near.any():
        return result
    rows = near.nonzero()[0]
    if len(rows) <= SCALAR_ROWS:
        # the usual case in traffic (none or one neighbour this close): the same tests on Python
        # floats, a fraction of the ~40 numpy calls below
        for k in rows.tolist():
            result[k] = _overlap(float(dx[k]), float(dy[k]), float(heading[k]), float(half_l[k]),
                                 float(half_w[k]), float(eh), half_el, half_ew)
        return result
    dx, dy, h = dx[near], dy[near], heading[near]
    hl, hw = half_l[near], half_w[near]
    ce, se = np.cos(eh), np.sin(eh)
    co, so = np.cos(h), np.sin(h)
    separated = np.zeros(len(dx), dtype=bool)
    # axes of the ego: along (ce, se) and across (-se, ce)
    for ax, ay, half_e in ((ce, se, half_el), (-se, ce, half_ew)):
        dist = np.abs(dx * ax + dy * ay)
        extent = hl * np.abs(co * ax + so * ay) + hw * np.abs(-so * ax + co * ay)
        separated |= dist > half_e + extent
    # axes of the others
    for ax, ay, half_o in ((co, so, hl), (-so, co, hw)):
        dist = np.abs(dx * ax + dy * ay)
        extent = half_el * np.abs(ce * ax + se * ay) + half_ew * np.abs(-se * ax + ce * ay)
        separated |= dist > half_o + extent
    result[rows] = ~separated
    return result


def _overlap(dx: float, dy: float, heading: float, hl: float, hw: float,
             ego_heading: float, half_el: float, half_ew: float) -> bool:
    """The separating-axis test of :func:`overlapping` for one rectangle, term by term on floats
    (``dx``, ``dy`` its centre from the ego's; ``hl``, ``hw`` its half sizes)."""
    ce, se = math.cos(ego_heading), math.sin(ego_heading)
    co, so = math.cos(heading), math.sin(heading)
    for ax, ay, half_e in ((ce, se, half_el), (-se, ce, half_ew)):
        extent = hl * abs(co * ax + so * ay) + hw * abs(-so * ax + co * ay)
        if abs(dx * ax + dy * ay) > half_e + extent:
            return False
    for ax, ay, half_o in ((co, so, hl), (-so, co, hw)):
        extent = half_el * abs(ce * ax + se * ay) + half_ew * abs(-se * ax + ce * ay)
        if abs(dx * ax + dy * ay) > half_o + extent:
            return False
    return True
