"""A rule-based driver: the baseline row of every comparison, and what runs before training exists.

* Path: the candidate nearest the ego when the episode starts, kept to the end (no path switching).
* Speed mode: the paper's traffic-light logic (SPEC §7, :func:`crossroads.idc.lights.choose_speed_mode`).
* Tracking: pure pursuit on the path for the steering angle, a proportional law on the mode's speed
  profile for the acceleration; both turned into the rates [Δδ, Δa] the ego takes as actions.
* Yielding: if a perceived participant is (or, at constant velocity, will be within a few seconds)
  on the path ahead, brake to stop short of it. Simple and conservative: it never negotiates gaps.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from crossroads.constants import (
    ACCEL_MAX,
    ACCEL_MIN,
    DT_S,
    EGO_LENGTH_M,
    JERK_MAX,
    L_F,
    L_R,
    STEER_MAX,
    STEER_RATE_MAX,
)
from crossroads.geometry import wrap_angle
from crossroads.idc.controller import Decision, SpeedMode
from crossroads.idc.lights import choose_speed_mode
from crossroads.planning import CandidatePath
from crossroads.sim.world import Observation

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
MIN_CHECK_DISTANCE_M = 10.0  # [m] the path ahead that is always checked for conflicts
CHECK_TIME_S = 3.0  # [s] plus the distance covered in this time at the current speed
SEARCH_BEHIND = 10  # path points searched behind the last nearest one (5 m at 0.5 m spacing)
SEARCH_AHEAD = 40  # ... and ahead of it (20 m: more than 0.1 s at any speed)


class RuleBasedController:
    """Pure pursuit + speed profile + traffic-light logic + simple yielding."""

    name = "rule"

    def __init__(self) -> None:
        self._candidates: tuple[CandidatePath, ...] = ()
        self._path_index: int | None = None
        self._point_hint = 0

    def reset(self, candidates: Sequence[CandidatePath]) -> None:
        self._candidates = tuple(candidates)
        self._path_index = None
        self._point_hint = 0

    def _progress(self, path: CandidatePath, x: float, y: float) -> float:
        """Arc length [m] of the path point nearest the ego, searched near the last one."""
        lo = max(0, self._point_hint - SEARCH_BEHIND)
        window = path.points[lo:self._point_hint + SEARCH_AHEAD]
        i = lo + int(np.argmin((window[:, 0] - x) ** 2 + (window[:, 1] - y) ** 2))
        self._point_hint = i
        return float(path.s[i])

    def decide(self, observation: Observation) -> Decision:
        ego = observation.ego
        x, y, vx, _, heading, _, delta, accel = ego
        if self._path_index is None:
            projections = [c.project(x, y) for c in self._candidates]
            self._path_index = int(np.argmin([abs(p.lateral_m) for p in projections]))
            self._point_hint = projections[self._path_index].index
        path = self._candidates[self._path_index]
        mode: SpeedMode = choose_speed_mode(
            front_vehicle_stopped_s=observation.front_vehicle_stopped_s,
            past_stop_line=observation.past_stop_line,
            light=observation.light.light,
            distance_to_stop_line_m=observation.distance_to_stop_line_m,
            speed_mps=float(vx),
            yellow_remaining_s=observation.light.remaining_s,
        )
        s_ego = self._progress(path, x, y)
        lookahead = LOOKAHEAD_BASE_M + LOOKAHEAD_PER_MPS * vx
        tx, ty, _, _ = path.reference_at(s_ego + lookahead, mode)
        alpha = wrap_angle(math.atan2(ty - y, tx - x) - heading)
        steer_target = math.atan2(2.0 * WHEELBASE_M * math.sin(alpha), lookahead)
        steer_target = float(np.clip(steer_target, -STEER_MAX, STEER_MAX))

        _, _, _, v_ref = path.reference_at(s_ego + max(vx, 1.0) * DT_S * 5, mode)
        accel_target = SPEED_GAIN * (v_ref - vx)
        conflict_s = self._conflict_distance(observation, path, s_ego, vx)
        if conflict_s is not None:
            gap = conflict_s - s_ego - EGO_LENGTH_M / 2.0 - STOP_GAP_M
            # uniform deceleration to a stop in the gap; full braking once the gap is gone
            stop_accel = -vx * vx / (2.0 * gap) if gap > 0.5 else ACCEL_MIN
            accel_target = min(accel_target, stop_accel)
        accel_target = float(np.clip(accel_target, ACCEL_MIN, ACCEL_MAX))
        action = np.array([
            np.clip(STEER_RATE_GAIN * (steer_target - delta), -STEER_RATE_MAX, STEER_RATE_MAX),
            np.clip(ACCEL_RATE_GAIN * (accel_target - accel), -JERK_MAX, JERK_MAX)])
        return Decision(action, self._path_index, mode)

    def _conflict_distance(self, obs: Observation, path: CandidatePath, s_ego: float,
                           vx: float) -> float | None:
        """Arc length of the first point on the path ahead that a perceived participant blocks."""
        reach = s_ego + max(MIN_CHECK_DISTANCE_M, vx * CHECK_TIME_S + MIN_CHECK_DISTANCE_M)
        seen = obs.perceived.observations
        # only those that could reach the checked stretch within the prediction horizon
        radius = reach - s_ego + EGO_LENGTH_M + seen[:, 2] * PREDICTION_HORIZON_S + CONFLICT_HALF_WIDTH_M
        seen = seen[np.hypot(seen[:, 0] - obs.ego[0], seen[:, 1] - obs.ego[1]) < radius]
        if len(seen) == 0:
            return None
        ahead = (path.s > s_ego + EGO_LENGTH_M / 2.0) & (path.s < reach)
        if not ahead.any():
            return None
        # every other path point (≤ 1 m apart) is fine against a corridor of over 2 m
        points, arc = path.points[ahead][::2], path.s[ahead][::2]
        times = np.arange(0.0, PREDICTION_HORIZON_S + 1e-9, PREDICTION_STEP_S)
        px = seen[:, 0, None] + np.cos(seen[:, 3, None]) * seen[:, 2, None] * times
        py = seen[:, 1, None] + np.sin(seen[:, 3, None]) * seen[:, 2, None] * times
        # squared distance of every predicted position (n, t) to every path point ahead (m)
        d2 = (px[:, :, None] - points[:, 0]) ** 2 + (py[:, :, None] - points[:, 1]) ** 2
        reach2 = (CONFLICT_HALF_WIDTH_M + seen[:, 5] / 2.0) ** 2
        blocked = (d2 < reach2[:, None, None]).any(axis=(0, 1))
        return float(arc[np.argmax(blocked)]) if blocked.any() else None
