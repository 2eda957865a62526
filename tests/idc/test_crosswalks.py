"""Crossings on the ego's path and the pedestrians that claim them (idc.crosswalks)."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import box

from crossroads.constants import EGO_WIDTH_M, STOP_LINE_GAP_M
from crossroads.idc.crosswalks import (
    CLAIM_HALF_WIDTH_M,
    CLAIM_HORIZON_MAX_S,
    CLEARING_ACCEL_MPS2,
    claimed,
    clearing_time_s,
    can_stand_short_of,
    crossing_spans,
    nearest_claimed,
)
from crossroads.intersections import catalogue
from crossroads.sim.config import WorldConfig
from crossroads.sim.world import World

# a straight path due east along y = 0, points every 0.5 m, and a 4 m crossing over it at x 20..24
PATH = np.column_stack([np.arange(0.0, 60.5, 0.5), np.zeros(121)])
S = PATH[:, 0].copy()
CROSSING = box(20.0, -10.0, 24.0, 10.0)


def _ped(x: float, y: float, v: float, phi: float) -> np.ndarray:
    return np.array([[x, y, v, phi, 0.3, 0.5]])


def test_a_span_starts_where_the_egos_half_width_reaches_the_crossing() -> None:
    (span,) = crossing_spans(PATH, S, [CROSSING])
    assert span.s_in_m == pytest.approx(20.0 - EGO_WIDTH_M / 2.0, abs=0.5)
    assert span.s_out_m == pytest.approx(24.0 + EGO_WIDTH_M / 2.0, abs=0.5)
    assert crossing_spans(PATH, S, [box(20.0, 5.0, 24.0, 10.0)]) == ()  # beside the path: no span


def test_who_claims_a_crossing() -> None:
    (span,) = crossing_spans(PATH, S, [CROSSING])
    assert claimed(span, _ped(22.0, 0.5, 0.0, np.pi / 2), 0.0)  # on it, in the ego's strip
    assert claimed(span, _ped(22.0, -6.0, 1.4, np.pi / 2), 3.0)  # walking toward the path, there within 3 s
    assert not claimed(span, _ped(22.0, -8.0, 1.0, np.pi / 2), 3.0)  # too far to reach the strip in 3 s
    assert claimed(span, _ped(22.0, -8.0, 1.0, np.pi / 2), 6.0)  # ... but not in 6 s (a slower ego)
    assert not claimed(span, _ped(22.0, -(CLAIM_HALF_WIDTH_M + 1.0), 1.3, -np.pi / 2), 6.0)  # walking away
    assert not claimed(span, _ped(30.0, 0.0, 1.3, np.pi / 2), 6.0)  # on the road past it, not on the crossing
    assert not claimed(span, np.zeros((0, 6)), 6.0)


def test_the_time_to_clear_a_crossing_grows_as_the_ego_slows() -> None:
    assert clearing_time_s(12.0, 6.0) == pytest.approx((-6.0 + np.sqrt(36.0 + 2 * CLEARING_ACCEL_MPS2 * 12.0)) / CLEARING_ACCEL_MPS2)
    assert clearing_time_s(12.0, 0.0) > clearing_time_s(12.0, 2.0) > clearing_time_s(12.0, 6.0)
    assert clearing_time_s(200.0, 0.0) == CLAIM_HORIZON_MAX_S and clearing_time_s(-1.0, 3.0) == 0.0


def test_the_line_is_the_nearest_claimed_crossing_ahead_if_the_ego_can_stand_short_of_it() -> None:
    spans = crossing_spans(PATH, S, [CROSSING])
    on_it = _ped(22.0, 0.0, 1.3, np.pi / 2)
    gap = spans[0].s_in_m - 5.0
    assert nearest_claimed(spans, 5.0, on_it, speed_mps=5.0) is spans[0] and gap > 0.0
    assert can_stand_short_of(gap, stopping_m=3.0)
    assert not can_stand_short_of(gap, stopping_m=gap - STOP_LINE_GAP_M + 0.1)  # too late
    assert nearest_claimed(spans, 5.0, np.zeros((0, 6)), speed_mps=5.0) is None  # nobody on it
    assert nearest_claimed(spans, spans[0].s_in_m + 0.5, on_it, speed_mps=0.0) is None  # already on it
    # someone 6 m out walking in at 1 m/s: in the way of an ego crawling up, not of one at 8 m/s
    walking_in = _ped(22.0, -6.0, 1.0, np.pi / 2)
    assert nearest_claimed(spans, 15.0, walking_in, speed_mps=0.5) is not None
    assert nearest_claimed(spans, 5.0, walking_in, speed_mps=8.0) is None


def test_the_nominal_left_turn_runs_over_the_crossings_of_its_entry_and_exit() -> None:
    with World(WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", warmup_s=1.0)) as world:
        obs = world.reset(1)
        assert len(obs.crossings) == 4
        for path in obs.candidates:
            spans = crossing_spans(path.points, path.s, obs.crossings)
            assert len(spans) == 2
            entry, exit_ = spans
            assert entry.s_in_m < path.s_stop_line + 1.0 < entry.s_out_m  # just past the stop line
            assert path.s_stop_line + 15.0 < exit_.s_in_m < path.s_exit  # where the turn ends


def _claimed_one_by_one(span, pedestrians: np.ndarray, horizon_s: float) -> bool:
    """claimed as first written: each pedestrian on its own, a shapely Point each."""
    from shapely.geometry import Point

    for px, py, v, phi, _, _ in np.asarray(pedestrians, np.float64).reshape(-1, 6):
        here = Point(px, py)
        if not span.area.contains(here):
            continue
        gap = span.centre.distance(here)
        if gap <= CLAIM_HALF_WIDTH_M:
            return True
        foot = span.centre.interpolate(span.centre.project(here))
        to_path = np.array([foot.x - px, foot.y - py]) / max(gap, 1e-9)
        closing = v * float(np.cos(phi) * to_path[0] + np.sin(phi) * to_path[1])
        if closing > 0.0 and gap - closing * horizon_s <= CLAIM_HALF_WIDTH_M:
            return True
    return False


def test_claimed_tests_everyone_at_once_as_it_tested_each() -> None:
    """claimed asks shapely about every pedestrian in one call (contains_xy, distance): the same
    verdicts as asking about each on its own, for crowds on, near and off a crossing, on its edges
    too, walking every way."""
    angle = np.linspace(0.0, np.pi / 2, 80)  # a left turn of 20 m radius, and a crossing over its middle
    turn = np.column_stack([20.0 * np.sin(angle), 20.0 - 20.0 * np.cos(angle)])
    turn_s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(turn, axis=0).T))])
    (straight,) = crossing_spans(PATH, S, [CROSSING])
    (curved,) = crossing_spans(turn, turn_s, [box(12.0, 2.0, 16.0, 10.0)])
    rng = np.random.default_rng(7)
    verdicts = []
    for k in range(2000):
        span = (straight, curved)[k % 2]
        x0, y0, x1, y1 = span.bounds
        n = int(rng.integers(0, 6))
        peds = np.column_stack([rng.uniform(x0 - 2.0, x1 + 2.0, n), rng.uniform(y0 - 2.0, y1 + 2.0, n),
                                rng.uniform(0.0, 2.0, n), rng.uniform(-np.pi, np.pi, n), np.full(n, 0.3), np.full(n, 0.5)])
        if n and rng.random() < 0.2:
            peds[0, :2] = [x0, rng.uniform(y0, y1)]  # on the edge of the widened area
        horizon = float(rng.uniform(0.0, CLAIM_HORIZON_MAX_S))
        verdict = claimed(span, peds, horizon)
        assert verdict == _claimed_one_by_one(span, peds, horizon)
        verdicts.append(verdict)
    assert 0 < sum(verdicts) < len(verdicts)
