"""How close an episode came to failing: the near-miss figures :func:`run_episode` reports.

A passed episode says nothing about how close it was to a crash or a red-light run; a search for
failures (``crossroads.search``) needs that grade to climb towards them. Three figures, each the
worst over the episode's observations, on the true states (never the noisy perception):

* ``min_gap_m``: the smallest gap between the ego's footprint and that of anyone it was closing in
  on (faster than ``CLOSING_MPS``; a queue standing bumper to bumper is no near miss), as the
  largest separation of the two rectangles along their four edge directions (the separating-axis
  test of :mod:`crossroads.sim.footprint` read as a distance). It never exceeds the true gap (equal
  when the nearest features are parallel edges, smaller corner to corner) and is ≤ 0 once they
  touch (counted then however slowly they met);
* ``min_ttc_s``: the shortest time to collision with someone ahead of the ego (in front of its
  centre, within ``TTC_RANGE_M``): the centres moving on at their present velocities would come
  within ``CONFLICT_RADIUS_M`` plus the two half widths, looked at ``TTC_HORIZON_S`` ahead; None
  when no such conflict ever arose. Those closing in from behind are theirs to avoid;
* ``red_stop_margin_m``: while the ego's light is red, it has not crossed the stop line and it
  moves (faster than ``CLOSING_MPS``), its distance to the line minus its braking distance at the
  hardest deceleration (``ACCEL_MIN``); the smallest over the episode. Negative: it could no longer
  stop before the line (the overshoot it would make); None when it never drove towards the line
  on red. Standing at the line is no near miss.
"""

from __future__ import annotations

import math

import numpy as np

from crossroads.constants import ACCEL_MIN, EGO_LENGTH_M, EGO_WIDTH_M
from crossroads.sim.observation import GroundTruth, Observation

GAP_RANGE_M = 30.0  # [m] centre distance beyond which a participant is not measured for the gap
TTC_RANGE_M = 50.0  # [m] centre distance beyond which a participant is not looked at for a TTC
TTC_HORIZON_S = 10.0  # [s] conflicts further ahead than this are not counted
CONFLICT_RADIUS_M = 1.0  # [m] added to the two half widths: centres this close count as a crash
MIN_CLOSING_MPS = 0.01  # [m/s] slower closing than this is no conflict (and no division by ~0)
CLOSING_MPS = 0.5  # [m/s] the gap counts when closing faster; the red margin when moving faster


class NearMissTracker:
    """Accumulates the near-miss figures over an episode's observations (:meth:`update` each)."""

    def __init__(self) -> None:
        self.min_distance_m = math.inf  # closest centre distance to anyone (inf: nobody around)
        self.min_gap_m = math.inf
        self.min_ttc_s = math.inf
        self.red_stop_margin_m = math.inf

    def update(self, observation: Observation, truth: GroundTruth) -> None:
        """Take in one step: the ego and its light from ``observation``, the others' true state."""
        ego = observation.ego
        x, y, heading = float(ego[0]), float(ego[1]), float(ego[4])
        snap = truth.participants
        if len(snap):
            dx, dy = snap.x - x, snap.y - y
            distance = np.hypot(dx, dy)
            self.min_distance_m = min(self.min_distance_m, float(distance.min()))
            c, s = math.cos(heading), math.sin(heading)
            vx = float(ego[2]) * c - float(ego[3]) * s  # body-frame speeds turned to the world
            vy = float(ego[2]) * s + float(ego[3]) * c
            wx, wy = snap.speed * np.cos(snap.heading) - vx, snap.speed * np.sin(snap.heading) - vy
            closing = -(dx * wx + dy * wy)  # > 0: the distance shrinks (times the distance)
            self._gap(dx, dy, distance, closing > CLOSING_MPS * distance, heading, snap.heading,
                      snap.length, snap.width)
            ahead = dx * c + dy * s > 0.0
            self._ttc(dx[ahead], dy[ahead], distance[ahead], wx[ahead], wy[ahead], snap.width[ahead])
        speed = max(float(ego[2]), 0.0)
        if (observation.light.light == "red" and observation.distance_to_stop_line_m >= 0.0
                and speed > CLOSING_MPS):
            margin = observation.distance_to_stop_line_m - speed * speed / (2.0 * -ACCEL_MIN)
            self.red_stop_margin_m = min(self.red_stop_margin_m, margin)

    def _gap(self, dx: np.ndarray, dy: np.ndarray, distance: np.ndarray, closing: np.ndarray,
             heading: float, headings: np.ndarray, lengths: np.ndarray, widths: np.ndarray) -> None:
        """``closing``: whether the ego and each participant close in on each other."""
        near = (distance <= GAP_RANGE_M).nonzero()[0]
        if len(near) == 0:
            return
        dx, dy, h = dx[near], dy[near], headings[near]
        half_l, half_w = lengths[near] / 2.0, widths[near] / 2.0
        half_el, half_ew = EGO_LENGTH_M / 2.0, EGO_WIDTH_M / 2.0
        ce, se = math.cos(heading), math.sin(heading)
        co, so = np.cos(h), np.sin(h)
        separation = np.full(len(near), -np.inf)
        for ax, ay, half_e in ((ce, se, half_el), (-se, ce, half_ew)):  # the ego's axes
            extent = half_l * np.abs(co * ax + so * ay) + half_w * np.abs(-so * ax + co * ay)
            separation = np.maximum(separation, np.abs(dx * ax + dy * ay) - half_e - extent)
        for ax, ay, half_o in ((co, so, half_l), (-so, co, half_w)):  # the others' axes
            extent = half_el * np.abs(ce * ax + se * ay) + half_ew * np.abs(-se * ax + ce * ay)
            separation = np.maximum(separation, np.abs(dx * ax + dy * ay) - half_o - extent)
        counted = separation[closing[near] | (separation <= 0.0)]
        if len(counted):
            self.min_gap_m = min(self.min_gap_m, float(counted.min()))

    def _ttc(self, dx: np.ndarray, dy: np.ndarray, distance: np.ndarray, wx: np.ndarray,
             wy: np.ndarray, widths: np.ndarray) -> None:
        """(dx, dy): where the others are from the ego; (wx, wy): their velocity relative to it."""
        closing = -(dx * wx + dy * wy)  # > 0: the distance shrinks (times the distance)
        rows = ((distance <= TTC_RANGE_M) & (closing > MIN_CLOSING_MPS * distance)).nonzero()[0]
        if len(rows) == 0:
            return
        px, py, vx, vy = dx[rows], dy[rows], wx[rows], wy[rows]
        w2 = vx * vx + vy * vy
        t_closest = closing[rows] / w2
        miss2 = (px + vx * t_closest) ** 2 + (py + vy * t_closest) ** 2
        radius = (EGO_WIDTH_M + widths[rows]) / 2.0 + CONFLICT_RADIUS_M
        hit = miss2 < radius * radius
        if not hit.any():
            return
        # when the centre distance first falls to the radius (0 if it is within it already)
        ttc = np.maximum(t_closest[hit] - np.sqrt((radius[hit] ** 2 - miss2[hit]) / w2[hit]), 0.0)
        ttc = ttc[ttc <= TTC_HORIZON_S]
        if len(ttc):
            self.min_ttc_s = min(self.min_ttc_s, float(ttc.min()))

    def figures(self) -> dict[str, float | None]:
        """The three figures (rounded to mm / ms), None where nothing was measured."""
        def rounded(value: float) -> float | None:
            return None if math.isinf(value) else round(value, 3)

        return {"min_gap_m": rounded(self.min_gap_m), "min_ttc_s": rounded(self.min_ttc_s),
                "red_stop_margin_m": rounded(self.red_stop_margin_m)}
