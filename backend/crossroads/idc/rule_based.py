"""A rule-based driver: the baseline row of every comparison, and what runs before training exists.

* Path: the candidate nearest the ego when the episode starts, kept to the end (no path switching).
* Speed mode: the paper's traffic-light logic (SPEC §7, :func:`crossroads.idc.lights.choose_speed_mode`).
* Tracking: pure pursuit on the path for the steering angle, a proportional law on the mode's speed
  profile for the acceleration, and in the stop mode a uniform deceleration to a stand just short of
  the stop line (``STOP_LINE_GAP_M``); both turned into the rates [Δδ, Δa] the ego takes as actions.
* Yielding: if a perceived participant is (or, at constant velocity, will be within a few seconds)
  on the path ahead, brake to stop short of it. Simple and conservative: it never negotiates gaps.
* Its body: the ego's footprint placed a few metres along the arc it steers for
  (:func:`body_sweep_conflict`) must not come nearer than now to anyone within a margin: a car
  turning swings its side, and the path ahead of its bumper alone missed a cyclist standing beside
  it (``f_irregular_wide``'s right turn, seed 1056386810 of base seed 20261206: the turn's inner
  side swept into it).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from crossroads.constants import (
    ACCEL_MAX,
    ACCEL_MIN,
    DT_S,
    EGO_LENGTH_M,
    EGO_WIDTH_M,
    JERK_MAX,
    L_F,
    L_R,
    STEER_MAX,
    STEER_RATE_MAX,
    STOP_LINE_GAP_M,
)
from crossroads.geometry import footprint_points, outside_box, wrap_scalar
from crossroads.idc.controller import Decision, SpeedMode
from crossroads.idc.lights import choose_speed_mode
from crossroads.planning import CandidatePath
from crossroads.sim.observation import Observation

WHEELBASE_M = L_F + L_R  # [m]
LOOKAHEAD_BASE_M = 4.0  # [m] pure-pursuit look-ahead at standstill
LOOKAHEAD_PER_MPS = 0.8  # [s] look-ahead grows with speed
SPEED_GAIN = 0.8  # [1/s] acceleration per m/s of speed error
ACCEL_RATE_GAIN = 4.0  # [1/s] how fast the acceleration follows its target (→ Δa)
STEER_RATE_GAIN = 6.0  # [1/s] how fast the steering follows its target (→ Δδ)
CONFLICT_HALF_WIDTH_M = 2.2  # [m] a participant this close to the path ahead blocks it
PREDICTION_HORIZON_S = 3.0  # [s] constant-velocity prediction of the others
PREDICTION_STEP_S = 0.5  # [s]
STOP_GAP_M = 3.0  # [m] stop this far short of a conflict (front bumper to conflict point)
# In the stop mode it stops the front bumper constants.STOP_LINE_GAP_M short of the stop line. Why a
# stop of its own and not the stop profile alone: the speed loop lags a falling reference by decel /
# SPEED_GAIN (1.16 / 0.8 ≈ 1.5 m/s), so it crossed a red line on an empty road at 1.7 m/s (measured)
MIN_CHECK_DISTANCE_M = 10.0  # [m] the path ahead that is always checked for conflicts
CHECK_TIME_S = 3.0  # [s] plus the distance covered in this time at the current speed
SEARCH_BEHIND = 10  # path points searched behind the last nearest one (5 m at 0.5 m spacing)
SEARCH_AHEAD = 40  # ... and ahead of it (20 m: more than 0.1 s at any speed)
PREDICTION_TIMES_S = np.arange(0.0, PREDICTION_HORIZON_S + 1e-9, PREDICTION_STEP_S)  # [s]
SWEEP_AHEAD_M = (0.5, 1.0, 2.0, 3.0)  # [m] along the arc the ego steers for: where its body is placed
SWEEP_MARGIN_M = 0.1  # [m] kept between the placed body and anyone else's (perceived positions are noisy)
SWEEP_NEAR_M = 10.0  # [m] no one farther from the ego's centre is looked at
CLOSING_M = 0.05  # [m] how much nearer than now counts as nearer
# [m] the ego's body widened by SWEEP_MARGIN_M, as a radius about its centre (and 1 mm for rounding)
_SWEPT_BODY_RADIUS_M = math.hypot(EGO_LENGTH_M / 2.0 + SWEEP_MARGIN_M, EGO_WIDTH_M / 2.0 + SWEEP_MARGIN_M) + 1e-3


@dataclass(frozen=True)
class _PathTable:
    """One candidate path as Python lists (per-episode constants of the controller's hot path).

    The controller interpolates the path twice a step at a single arc length: on Python floats
    and ``bisect`` that costs a fraction of :meth:`CandidatePath.reference_at` on numpy scalars
    (np.clip and np.searchsorted on one value, numpy scalar arithmetic), with the same
    arithmetic in the same order, so the same numbers (tests/idc/test_rule_based.py).
    """

    path: CandidatePath
    s: list[float]  # arc length of every point [m], non-decreasing
    x: list[float]
    y: list[float]
    heading: list[float]
    v: dict[str, list[float]]  # speed mode → reference speed at every point [m/s]
    length_m: float
    points_x: np.ndarray  # the points' x and y as contiguous arrays (the nearest-point search)
    points_y: np.ndarray

    @classmethod
    def of(cls, path: CandidatePath) -> _PathTable:
        x, y = path.points[:, 0], path.points[:, 1]
        return cls(path, path.s.tolist(), x.tolist(), y.tolist(), path.heading.tolist(),
                   {"pass": path.v_pass.tolist(), "stop": path.v_stop.tolist()}, path.length_m,
                   x.copy(), y.copy())

    def reference_at(self, s_m: float, mode: str) -> tuple[float, float, float, float]:
        """:meth:`CandidatePath.reference_at` (x, y, heading, speed) on Python floats."""
        s = self.s
        s_m = min(max(s_m, 0.0), self.length_m)
        i = min(max(bisect.bisect_right(s, s_m) - 1, 0), len(s) - 2)  # np.searchsorted(side="right")
        seg = s[i + 1] - s[i]
        w = 0.0 if seg <= 0.0 else (s_m - s[i]) / seg
        x = self.x[i] + w * (self.x[i + 1] - self.x[i])
        y = self.y[i] + w * (self.y[i + 1] - self.y[i])
        h0 = self.heading[i]
        h = wrap_scalar(h0 + w * wrap_scalar(self.heading[i + 1] - h0))
        profile = self.v[mode]
        return x, y, h, profile[i] + w * (profile[i + 1] - profile[i])


def arc_pose(x: float, y: float, heading: float, steer: float, distance_m: float) -> tuple[float, float, float]:
    """(x, y, heading) of the centre of gravity after ``distance_m`` [m] along the kinematic
    bicycle's arc at front wheel angle ``steer`` [rad] (slip angle β = atan(L_R tan δ / (L_F + L_R)),
    heading turning cos β tan δ / (L_F + L_R) per metre)."""
    beta = math.atan(L_R * math.tan(steer) / WHEELBASE_M)
    curvature = math.cos(beta) * math.tan(steer) / WHEELBASE_M
    direction = heading + beta
    if abs(curvature) < 1e-9:
        return x + distance_m * math.cos(direction), y + distance_m * math.sin(direction), heading
    turn = curvature * distance_m
    return (x + (math.sin(direction + turn) - math.sin(direction)) / curvature,
            y - (math.cos(direction + turn) - math.cos(direction)) / curvature,
            heading + turn)


def body_sweep_conflict(x: float, y: float, heading: float, steer: float, seen: np.ndarray) -> float | None:
    """How far [m] the ego's centre goes along its arc at front wheel angle ``steer``
    (:func:`arc_pose`, :data:`SWEEP_AHEAD_M`) before its body comes within :data:`SWEEP_MARGIN_M`
    of a participant's footprint (``seen``: perceived rows [x, y, v, φ, L, W]) and nearer than it
    is now, from (``x``, ``y``, ``heading``); None when it does not. Someone the ego is already
    near but drives away from, or past at the same distance, is no conflict. The arc, not the
    path: the ego a little off its path sets off from where it is."""
    if len(seen) == 0:
        return None
    near = seen[np.hypot(seen[:, 0] - x, seen[:, 1] - y) < SWEEP_NEAR_M]
    if len(near) == 0:
        return None
    cx, cy, h = np.array([(x, y, heading)] + [arc_pose(x, y, heading, steer, a) for a in SWEEP_AHEAD_M]).T
    # only those whose footprint reaches within the margin of the body at some placement: their
    # centre within their half-diagonal and the widened body's of that placement's centre
    reach = (np.hypot(0.5 * near[:, 4], 0.5 * near[:, 5]) + _SWEPT_BODY_RADIUS_M)[:, None]
    near = near[((near[:, 0, None] - cx[1:]) ** 2 + (near[:, 1, None] - cy[1:]) ** 2 <= reach**2).any(axis=1)]
    if len(near) == 0:
        return None
    px, py = footprint_points(near[:, 0], near[:, 1], near[:, 3], near[:, 4], near[:, 5])
    # the body now and at every placement at once: (n, 9 points, 1 + placements)
    gap = outside_box(px[:, :, None], py[:, :, None], cx, cy, h, EGO_LENGTH_M, EGO_WIDTH_M).min(axis=1)
    hit = ((gap[:, 1:] < SWEEP_MARGIN_M) & (gap[:, 1:] < gap[:, :1] - CLOSING_M)).any(axis=0)
    return SWEEP_AHEAD_M[int(hit.argmax())] if hit.any() else None


def _stop_within(speed: float, gap_m: float, least_gap_m: float) -> float:
    """The acceleration [m/s²] of a uniform deceleration from ``speed`` to a stand in ``gap_m``;
    full braking once the gap is down to ``least_gap_m``."""
    return -speed * speed / (2.0 * gap_m) if gap_m > least_gap_m else ACCEL_MIN


def _clip(x: float, lo: float, hi: float) -> float:
    """``np.clip`` of one Python float, without numpy's per-call overhead."""
    return min(max(x, lo), hi)


class RuleBasedController:
    """Pure pursuit + speed profile + traffic-light logic + simple yielding."""

    name = "rule"

    def __init__(self) -> None:
        self._candidates: tuple[CandidatePath, ...] = ()
        self._path_index: int | None = None
        self._point_hint = 0
        self._table: _PathTable | None = None

    def reset(self, candidates: Sequence[CandidatePath]) -> None:
        self._candidates = tuple(candidates)
        self._path_index = None
        self._point_hint = 0
        self._table = None

    def _progress(self, table: _PathTable, x: float, y: float) -> float:
        """Arc length [m] of the path point nearest the ego, searched near the last one."""
        lo = max(0, self._point_hint - SEARCH_BEHIND)
        hi = self._point_hint + SEARCH_AHEAD
        i = lo + int(((table.points_x[lo:hi] - x) ** 2 + (table.points_y[lo:hi] - y) ** 2).argmin())
        self._point_hint = i
        return table.s[i]

    def decide(self, observation: Observation) -> Decision:
        # Python floats from here on: numpy scalar arithmetic costs several times more per operation
        x, y, vx, _, heading, _, delta, accel = observation.ego.tolist()
        if self._path_index is None:
            projections = [c.project(x, y) for c in self._candidates]
            self._path_index = int(np.argmin([abs(p.lateral_m) for p in projections]))
            self._point_hint = projections[self._path_index].index
        path = self._candidates[self._path_index]
        if self._table is None or self._table.path is not path:
            self._table = _PathTable.of(path)
        table = self._table
        mode: SpeedMode = choose_speed_mode(
            front_vehicle_stopped_s=observation.front_vehicle_stopped_s,
            past_stop_line=observation.past_stop_line,
            light=observation.light.light,
            distance_to_stop_line_m=observation.distance_to_stop_line_m,
            speed_mps=vx,
            yellow_remaining_s=observation.light.remaining_s,
        )
        s_ego = self._progress(table, x, y)
        lookahead = LOOKAHEAD_BASE_M + LOOKAHEAD_PER_MPS * vx
        tx, ty, _, _ = table.reference_at(s_ego + lookahead, mode)
        alpha = wrap_scalar(math.atan2(ty - y, tx - x) - heading)
        steer_target = math.atan2(2.0 * WHEELBASE_M * math.sin(alpha), lookahead)
        steer_target = _clip(steer_target, -STEER_MAX, STEER_MAX)

        _, _, _, v_ref = table.reference_at(s_ego + max(vx, 1.0) * DT_S * 5, mode)
        accel_target = SPEED_GAIN * (v_ref - vx)
        if mode == "stop" and not observation.past_stop_line:
            line_gap = observation.distance_to_stop_line_m - STOP_LINE_GAP_M
            accel_target = min(accel_target, _stop_within(vx, line_gap, 0.2))
        conflict_s = self._conflict_distance(observation, table, s_ego, vx)
        swept_m = body_sweep_conflict(x, y, heading, steer_target, observation.perceived.observations)
        if swept_m is not None and (conflict_s is None or s_ego + swept_m < conflict_s):
            conflict_s = s_ego + swept_m
        if conflict_s is not None:
            gap = conflict_s - s_ego - EGO_LENGTH_M / 2.0 - STOP_GAP_M
            accel_target = min(accel_target, _stop_within(vx, gap, 0.5))
        accel_target = _clip(accel_target, ACCEL_MIN, ACCEL_MAX)
        action = np.array([
            _clip(STEER_RATE_GAIN * (steer_target - delta), -STEER_RATE_MAX, STEER_RATE_MAX),
            _clip(ACCEL_RATE_GAIN * (accel_target - accel), -JERK_MAX, JERK_MAX)])
        return Decision(action, self._path_index, mode)

    def _conflict_distance(self, obs: Observation, table: _PathTable, s_ego: float,
                           vx: float) -> float | None:
        """Arc length of the first point on the path ahead that a perceived participant blocks."""
        reach = s_ego + max(MIN_CHECK_DISTANCE_M, vx * CHECK_TIME_S + MIN_CHECK_DISTANCE_M)
        seen = obs.perceived.observations
        if len(seen) == 0:
            return None
        # only those that could reach the checked stretch within the prediction horizon
        radius = reach - s_ego + EGO_LENGTH_M + seen[:, 2] * PREDICTION_HORIZON_S + CONFLICT_HALF_WIDTH_M
        seen = seen[np.hypot(seen[:, 0] - obs.ego[0], seen[:, 1] - obs.ego[1]) < radius]
        if len(seen) == 0:
            return None
        # the path points with s_ego + L/2 < s < reach: one contiguous run, s being sorted
        s = table.s
        lo = bisect.bisect_right(s, s_ego + EGO_LENGTH_M / 2.0)
        hi = bisect.bisect_left(s, reach)
        if hi <= lo:
            return None
        # every other path point (≤ 1 m apart) is fine against a corridor of over 2 m
        qx, qy = table.path.points[lo:hi:2].T.copy()
        # each field of the few candidates as a contiguous row: cheaper operations than on columns
        x, y, v, phi, _, width = seen.T.copy()
        times = PREDICTION_TIMES_S
        px = x[:, None] + (np.cos(phi) * v)[:, None] * times
        py = y[:, None] + (np.sin(phi) * v)[:, None] * times
        # squared distance of every predicted position (n, t) to every path point ahead (m)
        d2 = (px[:, :, None] - qx) ** 2 + (py[:, :, None] - qy) ** 2
        reach2 = (CONFLICT_HALF_WIDTH_M + width / 2.0) ** 2
        blocked = (d2 < reach2[:, None, None]).reshape(-1, len(qx)).any(axis=0)
        first = int(blocked.argmax())  # the first blocked point, or 0 when none is
        return s[lo + 2 * first] if blocked[first] else None
