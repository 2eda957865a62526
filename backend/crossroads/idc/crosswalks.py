"""Pedestrian crossings on the ego's path: where they lie along it, and when a pedestrian claims one.

**(choice)** Not in the paper; used by the safety shield (:mod:`crossroads.idc.shield`). SUMO's
pedestrians walk over a crossing whatever stands on it, so an ego that stops with its front on a
crosswalk is walked into: with the shield holding the wheel, 15 of the 44 collisions of
200 nominal left turns (150 s timeout) were pedestrians walking into the ego's front, 14 at the exit
crosswalk and 1 at the entry, 10 of them into an ego standing still. Drivers stop short of a crosswalk that someone is
on, not on it: a claimed crossing is a line the shield holds the ego short of, as it holds a red
stop line — but only while full braking can still stop short of it, since stopping halfway onto
it is the very thing to avoid.

Pure geometry on numpy and shapely; the spans are per path and per episode, the claims per step.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon

from crossroads.constants import EGO_LENGTH_M, EGO_WIDTH_M, STOP_LINE_GAP_M

# [m] a pedestrian this close to a crossing's area counts as on it (stepping off the kerb)
ON_CROSSING_M = 1.0
# [m/s²] a pedestrian on a crossing claims it if it walks into the ego's strip before the ego, from
# its speed now and accelerating at this, has driven its whole length over the crossing. Why not a
# fixed time: with 3 s, on the 60 s nominal left, seed 1860059625, a pedestrian 6.2 m from the path
# did not claim the crossing while the ego crawled toward it at 0.6 m/s; when it did, the ego's front
# was on it, and the pedestrian walked into the standing ego. (choice) 1 m/s²: the pass profile's
# gentle pull-away, not the 1.5 m/s² limit.
CLEARING_ACCEL_MPS2 = 1.0
CLAIM_HORIZON_MAX_S = 8.0  # [s] no one farther out than this claims a crossing, however slow the ego
# [m] the strip either side of the ego's path a claiming pedestrian must be in or walk into: half the
# ego's width and the shield's 1 m clearance
CLAIM_HALF_WIDTH_M = EGO_WIDTH_M / 2.0 + 1.0


@dataclass(frozen=True)
class CrossingSpan:
    """The stretch of one path that runs over one crossing."""

    s_in_m: float  # [m] arc length where the ego's body first reaches the crossing's area
    s_out_m: float  # [m] arc length where its centre line leaves it
    area: Polygon  # the crossing's area, widened by ON_CROSSING_M (who counts as on it)
    centre: LineString  # the path's centre line over the crossing (whose strip a pedestrian claims)

    @functools.cached_property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) of ``area``, computed once: :func:`claimed` tests against it every step."""
        return self.area.bounds


def crossing_spans(points: np.ndarray, s: np.ndarray, crossings: Sequence[Polygon]) -> tuple[CrossingSpan, ...]:
    """The spans of a path (``points`` (n, 2) at arc lengths ``s`` (n,)) over the ``crossings``' areas,
    in path order: a point is over a crossing when the ego's half-width reaches its area."""
    out = []
    for area in crossings:
        idx = np.flatnonzero(shapely.contains_xy(area.buffer(EGO_WIDTH_M / 2.0), points[:, 0], points[:, 1]))
        if len(idx) == 0:
            continue
        lo, hi = int(idx[0]), int(idx[-1])
        centre = LineString(points[lo:hi + 1]) if hi > lo else LineString([points[lo], points[lo]])
        out.append(CrossingSpan(float(s[lo]), float(s[hi]), area.buffer(ON_CROSSING_M), centre))
    return tuple(sorted(out, key=lambda c: c.s_in_m))


def clearing_time_s(distance_m: float, speed_mps: float) -> float:
    """[s] for the ego to drive ``distance_m`` from ``speed_mps`` accelerating at CLEARING_ACCEL_MPS2
    (d = v t + a t² / 2 solved for t), at most CLAIM_HORIZON_MAX_S."""
    v, a = max(speed_mps, 0.0), CLEARING_ACCEL_MPS2
    t = (-v + math.sqrt(v * v + 2.0 * a * max(distance_m, 0.0))) / a
    return min(t, CLAIM_HORIZON_MAX_S)


def claimed(span: CrossingSpan, pedestrians: np.ndarray, horizon_s: float) -> bool:
    """Whether any of the perceived ``pedestrians`` (k, 6: p_x, p_y, v, φ, L, W) claims the crossing:
    on its area, and inside the strip of the ego's path there or walking into it within
    ``horizon_s`` (the ego's :func:`clearing_time_s`). Someone on the crossing but walking away from
    the path, or on its far part walking too slowly to reach the path in that time, does not."""
    peds = np.asarray(pedestrians, np.float64).reshape(-1, 6)
    x0, y0, x1, y1 = span.bounds  # a cheap test first: shapely costs microseconds a point
    peds = peds[(peds[:, 0] >= x0) & (peds[:, 0] <= x1) & (peds[:, 1] >= y0) & (peds[:, 1] <= y1)]
    if len(peds) == 0:
        return False
    # who is on it, how far from the path, and the nearest point of the path: shapely's vectorised
    # forms of area.contains, centre.distance, centre.project and centre.interpolate of a Point,
    # one call each for everyone instead of one each a pedestrian
    peds = peds[shapely.contains_xy(span.area, peds[:, 0], peds[:, 1])]
    here = shapely.points(peds[:, :2])
    gaps = shapely.distance(span.centre, here)
    if (gaps <= CLAIM_HALF_WIDTH_M).any():
        return True
    feet = shapely.get_coordinates(shapely.line_interpolate_point(span.centre, shapely.line_locate_point(span.centre, here)))
    # the walking direction against the direction to the nearest point of the path
    to_path = (feet - peds[:, :2]) / np.maximum(gaps, 1e-9)[:, None]
    closing = peds[:, 2] * (np.cos(peds[:, 3]) * to_path[:, 0] + np.sin(peds[:, 3]) * to_path[:, 1])  # [m/s] toward the path
    return bool(((closing > 0.0) & (gaps - closing * horizon_s <= CLAIM_HALF_WIDTH_M)).any())


def claims_ahead(span: CrossingSpan, front_s_m: float, pedestrians: np.ndarray, speed_mps: float) -> bool:
    """Whether someone of ``pedestrians`` claims ``span`` against an ego whose front bumper is at arc
    length ``front_s_m``, at ``speed_mps``: :func:`claimed` within the time the ego needs to get its
    rear past the crossing (the front must leave it by the ego's length)."""
    return claimed(span, pedestrians, clearing_time_s(span.s_out_m - front_s_m + EGO_LENGTH_M, speed_mps))


def nearest_claimed(spans: Sequence[CrossingSpan], front_s_m: float, pedestrians: np.ndarray,
                    speed_mps: float) -> CrossingSpan | None:
    """The nearest crossing ahead on the path (``spans`` of it, the bumper at arc length
    ``front_s_m``, the ego at ``speed_mps``) that a pedestrian claims, or None. A crossing the bumper
    is on or past is not ahead: the ego drives on over it."""
    for span in spans:
        if span.s_in_m - front_s_m >= 0.0 and claims_ahead(span, front_s_m, pedestrians, speed_mps):
            return span
    return None


def can_stand_short_of(gap_m: float, stopping_m: float) -> bool:
    """Whether full braking (``stopping_m``) stands the ego ``STOP_LINE_GAP_M`` short of a crossing
    ``gap_m`` ahead. Too late, the shield does not hold it short: stopping halfway onto the crossing
    is the very thing to avoid, so the ego drives on and the participant checks remain."""
    return stopping_m + STOP_LINE_GAP_M <= gap_m
