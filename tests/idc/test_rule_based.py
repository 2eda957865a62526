"""The rule-based driver's fast paths (floats, a per-path table) drive exactly as the plain
numpy formulation it was first written in."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crossroads.constants import (ACCEL_MAX, ACCEL_MIN, DT_S, EGO_LENGTH_M, EGO_WIDTH_M, JERK_MAX, STEER_MAX, STEER_RATE_MAX,
                                 STOP_LINE_GAP_M)
from crossroads.geometry import footprint_points, outside_box, wrap_angle
from crossroads.idc import rule_based as R
from crossroads.idc.lights import choose_speed_mode
from crossroads.intersections import catalogue
from crossroads.planning import plan_candidates
from crossroads.sim.config import SignalStart, WorldConfig
from crossroads.sim.traffic import NO_TRAFFIC
from crossroads.sim.world import World
from planning.factories import four_way_junction


class _PlainController:
    """RuleBasedController as first written (numpy scalars, CandidatePath.reference_at, masks)."""

    def reset(self, candidates):
        self._candidates, self._path_index, self._point_hint = tuple(candidates), None, 0

    def _progress(self, path, x, y):
        lo = max(0, self._point_hint - R.SEARCH_BEHIND)
        window = path.points[lo:self._point_hint + R.SEARCH_AHEAD]
        i = lo + int(np.argmin((window[:, 0] - x) ** 2 + (window[:, 1] - y) ** 2))
        self._point_hint = i
        return float(path.s[i])

    def decide(self, observation):
        x, y, vx, _, heading, _, delta, accel = observation.ego
        if self._path_index is None:
            projections = [c.project(x, y) for c in self._candidates]
            self._path_index = int(np.argmin([abs(p.lateral_m) for p in projections]))
            self._point_hint = projections[self._path_index].index
        path = self._candidates[self._path_index]
        mode = choose_speed_mode(
            front_vehicle_stopped_s=observation.front_vehicle_stopped_s, past_stop_line=observation.past_stop_line,
            light=observation.light.light, distance_to_stop_line_m=observation.distance_to_stop_line_m,
            speed_mps=float(vx), yellow_remaining_s=observation.light.remaining_s)
        s_ego = self._progress(path, x, y)
        lookahead = R.LOOKAHEAD_BASE_M + R.LOOKAHEAD_PER_MPS * vx
        tx, ty, _, _ = path.reference_at(s_ego + lookahead, mode)
        alpha = wrap_angle(math.atan2(ty - y, tx - x) - heading)
        steer_target = float(np.clip(math.atan2(2.0 * R.WHEELBASE_M * math.sin(alpha), lookahead), -STEER_MAX, STEER_MAX))
        _, _, _, v_ref = path.reference_at(s_ego + max(vx, 1.0) * DT_S * 5, mode)
        accel_target = R.SPEED_GAIN * (v_ref - vx)
        if mode == "stop" and not observation.past_stop_line:
            line_gap = observation.distance_to_stop_line_m - STOP_LINE_GAP_M
            accel_target = min(accel_target, -vx * vx / (2.0 * line_gap) if line_gap > 0.2 else ACCEL_MIN)
        conflict_s = self.conflict_distance(observation, path, s_ego, vx)
        if conflict_s is not None:
            gap = conflict_s - s_ego - EGO_LENGTH_M / 2.0 - R.STOP_GAP_M
            accel_target = min(accel_target, -vx * vx / (2.0 * gap) if gap > 0.5 else ACCEL_MIN)
        accel_target = float(np.clip(accel_target, ACCEL_MIN, ACCEL_MAX))
        action = np.array([np.clip(R.STEER_RATE_GAIN * (steer_target - delta), -STEER_RATE_MAX, STEER_RATE_MAX),
                           np.clip(R.ACCEL_RATE_GAIN * (accel_target - accel), -JERK_MAX, JERK_MAX)])
        return action, self._path_index, mode

    @staticmethod
    def conflict_distance(obs, path, s_ego, vx):
        reach = s_ego + max(R.MIN_CHECK_DISTANCE_M, vx * R.CHECK_TIME_S + R.MIN_CHECK_DISTANCE_M)
        seen = obs.perceived.observations
        radius = reach - s_ego + EGO_LENGTH_M + seen[:, 2] * R.PREDICTION_HORIZON_S + R.CONFLICT_HALF_WIDTH_M
        seen = seen[np.hypot(seen[:, 0] - obs.ego[0], seen[:, 1] - obs.ego[1]) < radius]
        if len(seen) == 0:
            return None
        ahead = (path.s > s_ego + EGO_LENGTH_M / 2.0) & (path.s < reach)
        if not ahead.any():
            return None
        points, arc = path.points[ahead][::2], path.s[ahead][::2]
        times = np.arange(0.0, R.PREDICTION_HORIZON_S + 1e-9, R.PREDICTION_STEP_S)
        px = seen[:, 0, None] + np.cos(seen[:, 3, None]) * seen[:, 2, None] * times
        py = seen[:, 1, None] + np.sin(seen[:, 3, None]) * seen[:, 2, None] * times
        d2 = (px[:, :, None] - points[:, 0]) ** 2 + (py[:, :, None] - points[:, 1]) ** 2
        reach2 = (R.CONFLICT_HALF_WIDTH_M + seen[:, 5] / 2.0) ** 2
        blocked = (d2 < reach2[:, None, None]).any(axis=(0, 1))
        return float(arc[np.argmax(blocked)]) if blocked.any() else None


def test_path_table_is_reference_at() -> None:
    rng = np.random.default_rng(0)
    for path in plan_candidates(four_way_junction(n_lanes=2), "left"):
        table = R._PathTable.of(path)
        grid = np.concatenate([np.linspace(-5, path.length_m + 5, 2001), path.s, rng.uniform(0, path.length_m, 500)])
        for s in grid.tolist():
            for mode in ("pass", "stop"):
                assert table.reference_at(s, mode) == path.reference_at(s, mode)


@pytest.mark.parametrize("seed", [1, 5])
def test_drives_as_the_plain_formulation(seed: int) -> None:
    """Whole episodes in real traffic: the same action, path and mode at every step."""
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", warmup_s=40.0, timeout_s=25.0)
    with World(config) as world:
        obs = world.reset(seed)
        fast, plain = R.RuleBasedController(), _PlainController()
        fast.reset(world.candidates)
        plain.reset(world.candidates)
        conflicts = 0
        for _ in range(250):
            decision = fast.decide(obs)
            action, path_index, mode = plain.decide(obs)
            assert decision.action.tobytes() == action.tobytes()
            assert (decision.path_index, decision.speed_mode) == (path_index, mode)
            path = world.candidates[path_index]
            s_ego = float(path.s[fast._point_hint])
            expected = plain.conflict_distance(obs, path, s_ego, float(obs.ego[2]))
            assert fast._conflict_distance(obs, fast._table, s_ego, float(obs.ego[2])) == expected
            conflicts += expected is not None
            obs, outcome = world.step(decision.action)
            if outcome is not None:
                break
        assert conflicts > 0  # the yielding check was exercised


def test_stops_at_a_red_line_and_goes_on_green() -> None:
    """On an empty road, starting 40 m from a red line at 8.33 m/s: the front bumper stands within a
    metre short of the line (measured: 0.49 m) until green, then the turn is passed. Before its stop
    of its own the speed loop lagged the stop profile and crossed the red line at 1.7 m/s."""
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", demand=NO_TRAFFIC,
                         signal_start=SignalStart(phase_index=2), warmup_s=1.0, timeout_s=60.0)
    with World(config) as world:
        obs = world.reset(0)
        controller = R.RuleBasedController()
        controller.reset(world.candidates)
        gaps_standing_on_red = []
        outcome = None
        while outcome is None:
            if obs.light.light == "red" and obs.ego[2] < 0.05:
                gaps_standing_on_red.append(obs.distance_to_stop_line_m)
            obs, outcome = world.step(controller.decide(obs).action)
    assert outcome.kind == "passed", outcome
    assert len(gaps_standing_on_red) > 100  # it waited for the green (the ego's red lasts 40 s here)
    assert 0.0 < min(gaps_standing_on_red) and max(gaps_standing_on_red) < 1.0


def test_the_arc_is_straight_without_steering_and_bends_the_way_it_steers() -> None:
    assert R.arc_pose(1.0, 2.0, 0.0, 0.0, 3.0) == pytest.approx((4.0, 2.0, 0.0))
    x, y, heading = R.arc_pose(0.0, 0.0, 0.0, -0.3, 3.0)  # steering right
    assert y < 0.0 and heading < 0.0 and 2.5 < x < 3.0
    # small steps of the same arc add up to it
    px, py, ph = 0.0, 0.0, 0.0
    for _ in range(30):
        px, py, ph = R.arc_pose(px, py, ph, -0.3, 0.1)
    assert (px, py, ph) == pytest.approx((x, y, heading), abs=1e-9)


def _seen(*rows: tuple[float, float, float, float, float, float]) -> np.ndarray:
    return np.array(rows, dtype=float).reshape(-1, 6)


def test_the_body_sweep_stops_for_a_cyclist_standing_beside_the_inner_side_of_a_turn() -> None:
    # the ego at the origin heading +x (its right side at y = -1); a cyclist standing parallel 0.15 m off it
    cyclist = _seen((-0.5, -1.0 - 0.15 - 0.325, 0.0, 0.0, 1.6, 0.65))
    assert R.body_sweep_conflict(0.0, 0.0, 0.0, -0.35, cyclist) is not None  # turning right swings into it
    assert R.body_sweep_conflict(0.0, 0.0, 0.0, 0.0, cyclist) is None  # straight on: past it at the same distance
    # turning left: its side away from it, its tail swinging out 0.1 m (over 1 m at 0.35 rad): 0.3 m off is clear
    assert R.body_sweep_conflict(0.0, 0.0, 0.0, 0.35, _seen((-0.5, -1.0 - 0.3 - 0.325, 0.0, 0.0, 1.6, 0.65))) is None
    far = _seen((-0.5, -1.0 - 1.0 - 0.325, 0.0, 0.0, 1.6, 0.65))  # 1 m off: the turn's sweep does not reach it
    assert R.body_sweep_conflict(0.0, 0.0, 0.0, -0.35, far) is None
    assert R.body_sweep_conflict(0.0, 0.0, 0.0, -0.35, _seen()) is None


def _plain_body_sweep_conflict(x, y, heading, steer, seen):
    """body_sweep_conflict with every participant within SWEEP_NEAR_M checked at every placement."""
    near = seen[np.hypot(seen[:, 0] - x, seen[:, 1] - y) < R.SWEEP_NEAR_M]
    if len(near) == 0:
        return None
    px, py = footprint_points(near[:, 0], near[:, 1], near[:, 3], near[:, 4], near[:, 5])
    cx, cy, h = np.array([(x, y, heading)] + [R.arc_pose(x, y, heading, steer, a) for a in R.SWEEP_AHEAD_M]).T
    gap = outside_box(px[:, :, None], py[:, :, None], cx, cy, h, EGO_LENGTH_M, EGO_WIDTH_M).min(axis=1)
    hit = ((gap[:, 1:] < R.SWEEP_MARGIN_M) & (gap[:, 1:] < gap[:, :1] - R.CLOSING_M)).any(axis=0)
    return R.SWEEP_AHEAD_M[int(hit.argmax())] if hit.any() else None


def test_body_sweep_conflict_answers_as_the_plain_formulation() -> None:
    rng = np.random.default_rng(20261207)
    found = []
    for _ in range(1500):
        n = int(rng.integers(0, 8))
        x, y, heading = float(rng.uniform(-30, 30)), float(rng.uniform(-30, 30)), float(rng.uniform(-math.pi, math.pi))
        steer = float(rng.uniform(-STEER_MAX, STEER_MAX))
        seen = np.column_stack([x + rng.uniform(-11, 11, n), y + rng.uniform(-11, 11, n), rng.uniform(0, 10, n),
                                rng.uniform(-math.pi, math.pi, n), rng.uniform(0.4, 12.0, n), rng.uniform(0.4, 2.5, n)])
        answer = R.body_sweep_conflict(x, y, heading, steer, seen)
        assert answer == _plain_body_sweep_conflict(x, y, heading, steer, seen)
        found.append(answer)
    assert sum(a is not None for a in found) > 100  # conflicts drawn, at several placements
    assert len({a for a in found if a is not None}) >= 3
