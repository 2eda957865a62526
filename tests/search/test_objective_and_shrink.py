"""The near-miss objective and the shrinking state machine (driven by a plain rule for failing)."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import pytest

from crossroads.search.objective import FAILURE_VALUE, GAP_SCALE_M, TTC_SCALE_S, margin, objective
from crossroads.search.shrink import Shrinker
from crossroads.search.space import Parameter

FAILS = ("collision", "red_light", "off_road")


def test_failures_score_lowest_and_near_misses_below_comfortable_episodes() -> None:
    assert objective({"outcome": "collision"}, FAILS) == FAILURE_VALUE
    assert objective({"outcome": "red_light"}, ["collision"]) != FAILURE_VALUE  # not asked for
    comfortable = {"outcome": "passed", "min_gap_m": 5.0, "min_ttc_s": None, "red_stop_margin_m": 40.0}
    close = {"outcome": "passed", "min_gap_m": 0.5, "min_ttc_s": 2.0, "red_stop_margin_m": None}
    assert objective(comfortable, FAILS) == 1.0
    assert objective(close, FAILS) == pytest.approx(min(0.5 / GAP_SCALE_M, 2.0 / TTC_SCALE_S))
    overshoot = {"outcome": "timeout", "min_gap_m": 3.0, "red_stop_margin_m": -1.2}
    assert objective(overshoot, FAILS) == 0.0
    assert margin({"outcome": "passed"}) == 1.0  # nothing measured
    assert objective(None, FAILS) is None
    assert objective({"outcome": "error"}, FAILS) is None


def _shrink(parameters: list[Parameter], start: Mapping[str, float], nominal: Mapping[str, float],
            fails: Callable[[Mapping[str, float]], bool], max_steps: int = 100) -> tuple[dict[str, float], int]:
    shrinker = Shrinker(parameters, start, nominal, "collision", max_steps=max_steps)
    tried = 0
    while (step := shrinker.candidate()) is not None:
        tried += 1
        shrinker.tell("collision" if fails(step.params) else "passed")
    return shrinker.current, tried


PARAMS = [Parameter(path="abnormal.overspeed.share", low=0.0, high=1.0),
          Parameter(path="traffic.vehicles_per_hour", low=0.0, high=800.0),
          Parameter(path="lights.phase", choices=[0, 1, 4])]
NOMINAL = {"abnormal.overspeed.share": 0.0, "traffic.vehicles_per_hour": 400.0, "lights.phase": 0}


def test_what_the_failure_does_not_need_goes_back_to_nominal() -> None:
    start = {"abnormal.overspeed.share": 0.8, "traffic.vehicles_per_hour": 700.0, "lights.phase": 4}
    current, tried = _shrink(PARAMS, start, NOMINAL, lambda p: p["lights.phase"] == 4)
    assert current == {"abnormal.overspeed.share": 0.0, "traffic.vehicles_per_hour": 400.0, "lights.phase": 4}
    # share to 0 (kept), traffic to 400 (kept), phase to 0 (not failing; no halfway for a choice)
    assert tried == 3


def test_a_parameter_the_failure_needs_moves_halfway_at_most() -> None:
    start = {"abnormal.overspeed.share": 0.8, "traffic.vehicles_per_hour": 400.0, "lights.phase": 0}
    current, tried = _shrink(PARAMS, start, NOMINAL, lambda p: p["abnormal.overspeed.share"] >= 0.3)
    assert current["abnormal.overspeed.share"] == pytest.approx(0.4)  # 0 fails not; halfway does
    assert tried == 2
    current, _ = _shrink(PARAMS, start, NOMINAL, lambda p: p["abnormal.overspeed.share"] >= 0.5)
    assert current["abnormal.overspeed.share"] == 0.8  # neither 0 nor 0.4 fails: it stays


def test_a_different_failure_is_no_step_and_the_budget_is_kept() -> None:
    start = {"abnormal.overspeed.share": 0.8, "traffic.vehicles_per_hour": 700.0, "lights.phase": 4}
    shrinker = Shrinker(PARAMS, start, NOMINAL, "collision", max_steps=2)
    first = shrinker.candidate()
    assert first is not None and first.path == "abnormal.overspeed.share" and first.params["abnormal.overspeed.share"] == 0.0
    shrinker.tell("red_light")  # fails, but otherwise: not the same failure
    halfway = shrinker.candidate()
    assert halfway is not None and halfway.params["abnormal.overspeed.share"] == pytest.approx(0.4)
    shrinker.tell("collision")
    assert shrinker.candidate() is None and shrinker.done  # two steps were allowed
    assert shrinker.current["abnormal.overspeed.share"] == pytest.approx(0.4)
    with pytest.raises(RuntimeError):
        shrinker.tell("collision")


def test_whole_numbers_round_towards_nominal() -> None:
    params = [Parameter(path="lights.phase", low=0, high=7)]
    current, _ = _shrink(params, {"lights.phase": 7}, {"lights.phase": 0}, lambda p: p["lights.phase"] >= 3)
    assert current == {"lights.phase": 3.0}  # 0 passes; halfway 3.5 rounds down to 3, which fails
