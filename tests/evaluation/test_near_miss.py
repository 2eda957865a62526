"""The near-miss figures: footprint gap, time to collision, stopping margin on red."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from crossroads.constants import EGO_LENGTH_M, EGO_WIDTH_M
from crossroads.evaluation.episode import run_episode
from crossroads.evaluation.near_miss import CONFLICT_RADIUS_M, NearMissTracker
from crossroads.scenario.spec import load_scenario, to_world_config
from crossroads.idc.rule_based import RuleBasedController
from crossroads.sim.world import World
from support import REPO_ROOT


def _gap(dx: float, dy: float, heading: float, length: float = 4.0, width: float = 2.0) -> float:
    tracker = NearMissTracker()
    a = np.array
    tracker._gap(a([dx]), a([dy]), np.hypot(a([dx]), a([dy])), a([True]), 0.0, a([heading]), a([length]),
                 a([width]))
    return tracker.min_gap_m


def test_the_gap_of_parallel_rectangles_is_exact_and_negative_when_they_overlap() -> None:
    # side by side, 3.5 m apart centre to centre: 3.5 − 1 − 1 = 1.5 m
    assert _gap(0.0, 3.5, 0.0) == pytest.approx(1.5)
    # nose to tail, 10 m apart: 10 − 2.4 − 2 = 5.6 m
    assert _gap(10.0, 0.0, 0.0) == pytest.approx(10.0 - EGO_LENGTH_M / 2 - 2.0)
    assert _gap(1.0, 0.5, 0.3) < 0.0
    # corner to corner the figure stays below the true distance
    true_corner_gap = np.hypot(6.0 - EGO_LENGTH_M / 2 - 2.0, 4.0 - EGO_WIDTH_M / 2 - 1.0)
    assert _gap(6.0, 4.0, 0.0) <= true_corner_gap


def test_a_gap_counts_only_when_closing_in_or_touching() -> None:
    tracker = NearMissTracker()
    a = np.array
    standing = dict(heading=0.0, headings=a([0.0]), lengths=a([4.0]), widths=a([2.0]))
    tracker._gap(a([6.0]), a([0.0]), a([6.0]), a([False]), **standing)  # a queue, 0.6 m apart
    assert tracker.figures()["min_gap_m"] is None
    tracker._gap(a([4.0]), a([0.0]), a([4.0]), a([False]), **standing)  # touching, however slowly
    assert tracker.min_gap_m == pytest.approx(4.0 - EGO_LENGTH_M / 2 - 2.0)


def test_time_to_collision_of_a_head_on_approach_and_none_for_a_passing_one() -> None:
    tracker = NearMissTracker()
    a = np.array
    # 30 m ahead, closing at 10 m/s on the ego's axis, 1.8 m wide
    tracker._ttc(a([30.0]), a([0.0]), a([30.0]), a([-10.0]), a([0.0]), a([1.8]))
    radius = (EGO_WIDTH_M + 1.8) / 2 + CONFLICT_RADIUS_M
    assert tracker.min_ttc_s == pytest.approx((30.0 - radius) / 10.0)
    passing = NearMissTracker()  # 6 m to the side: it never comes within the radius
    passing._ttc(a([30.0]), a([6.0]), a([np.hypot(30.0, 6.0)]), a([-10.0]), a([0.0]), a([1.8]))
    assert passing.figures()["min_ttc_s"] is None
    leaving = NearMissTracker()
    leaving._ttc(a([30.0]), a([0.0]), a([30.0]), a([10.0]), a([0.0]), a([1.8]))
    assert leaving.figures()["min_ttc_s"] is None


def test_an_episode_reports_the_figures_and_a_red_light_run_has_a_negative_margin() -> None:
    spec = load_scenario(REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-left.yaml")
    # the cross street's green (the ego's red) with the ego 4 m before the line at 10 m/s
    red = spec.model_copy(update={
        "lights": spec.lights.model_copy(update={"phase": 4}),
        "ego": spec.ego.model_copy(update={"start_distance_m": 4.0, "start_speed_mps": 10.0})})
    with World(replace(to_world_config(red), warmup_s=5.0, timeout_s=10.0)) as world:
        result = run_episode(world, RuleBasedController(), seed=3)
    assert result.outcome == "red_light"
    assert result.red_stop_margin_m is not None and result.red_stop_margin_m < 0.0
    data = result.to_json()
    assert {"min_gap_m", "min_ttc_s", "red_stop_margin_m"} <= data.keys()
