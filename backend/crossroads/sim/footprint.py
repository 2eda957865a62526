"""True footprints: oriented rectangles and their overlap (separating axis theorem), vectorised.

Used to judge collisions on the participants' real poses and sizes, never on the noisy ones.
"""

from __future__ import annotations

import numpy as np

from crossroads.geometry import FloatArray


def rectangle_corners(x: float, y: float, heading: float, length: float, width: float) -> FloatArray:
    """The four corners (4, 2) of a rectangle centred at (x, y) [m], long axis along ``heading``."""
    c, s = np.cos(heading), np.sin(heading)
    forward = np.array([c, s]) * (length / 2.0)
    left = np.array([-s, c]) * (width / 2.0)
    centre = np.array([x, y])
    return np.array([centre + forward + left, centre - forward + left,
                     centre - forward - left, centre + forward - left])


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
    near = np.hypot(dx, dy) <= np.hypot(half_el, half_ew) + np.hypot(half_l, half_w)
    result = np.zeros(n, dtype=bool)
    if not near.any():
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
    result[np.flatnonzero(near)] = ~separated
    return result
