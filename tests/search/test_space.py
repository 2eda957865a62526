"""Search spaces: validation that names the field, the scenario of a point, distances, seeds."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from crossroads.scenario.spec import load_scenario, run_seeds
from crossroads.search.space import (
    draw_seed,
    load_space,
    network_problems_of,
    scenario_for,
    seed_pool,
    validate_space,
)
from crossroads.validation import SpecError
from support import REPO_ROOT

NOMINAL = REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-left.yaml"
EXAMPLE = REPO_ROOT / "scenarios" / "search" / "c_three_lane-left.yaml"


def space_data(**changes: Any) -> dict[str, Any]:
    data: dict[str, Any] = {
        "version": 1, "name": "t", "scenario": str(NOMINAL),
        "parameters": [
            {"path": "abnormal.overspeed.share", "low": 0.0, "high": 0.5},
            {"path": "traffic.vehicles_per_hour", "low": 200, "high": 800},
            {"path": "lights.phase", "choices": [0, 4]},
            {"path": "ego.start_distance_m", "low": 20.0, "high": 50.0},
        ],
    }
    data.update(changes)
    return data


def problems(data: dict[str, Any]) -> dict[str, str]:
    with pytest.raises(SpecError) as info:
        validate_space(data, source="space.yaml")
    assert info.value.source == "space.yaml"
    return dict(info.value.problems)


def test_the_example_space_loads_and_its_network_agrees() -> None:
    space = load_space(EXAMPLE)
    assert len(space.parameters) == 10
    assert space.failures == ("collision", "red_light", "off_road")
    assert network_problems_of(space) == []
    nominal = space.nominal_values()
    assert nominal["abnormal.overspeed.share"] == 0.0  # absent from the nominal scenario
    assert nominal["lights.phase"] == 0 and isinstance(nominal["lights.phase"], int)
    assert nominal["traffic.vehicles_per_hour"] == 400.0


@pytest.mark.parametrize(("change", "field", "words"), [
    ({"parameters": [{"path": "ego.colour", "low": 0, "high": 1}]}, "parameters.0.path", "unknown parameter"),
    ({"parameters": [{"path": "warmup_s", "low": 5.0, "high": 5.0}]}, "parameters.0.high", "above low"),
    ({"parameters": [{"path": "warmup_s", "low": 5.0}]}, "parameters.0.low", "give low and high"),
    ({"parameters": [{"path": "warmup_s", "low": 1.0, "high": 2.0, "choices": [1.0]}]},
     "parameters.0.choices", "not both"),
    ({"parameters": [{"path": "lights.phase", "low": 0, "high": 2.5}]}, "parameters.0.low", "whole numbers"),
    ({"parameters": [{"path": "warmup_s", "low": 1.0, "high": 2.0},
                     {"path": "warmup_s", "low": 1.0, "high": 3.0}]}, "parameters.1.path", "twice"),
    ({"parameters": [{"path": "abnormal.rounding.share", "low": 0.0, "high": 1.5}]},
     "parameters.0", "makes no valid scenario"),
    ({"parameters": []}, "parameters", "at least 1"),
    ({"failures": ["timeout"]}, "failures.0", ""),
    ({"seed": {"low": 10, "high": 5}}, "seed.high", "at least low"),
    ({"seed": {"low": 10, "high": 12, "pool": 4}}, "seed.pool", "holds only 3 seeds"),
    ({"seed": {"pool": 1}}, "seed.pool", "greater than or equal to 2"),
    ({"scenario": "missing.yaml"}, "scenario", "not found"),
    ({"version": 2}, "version", ""),
])
def test_a_bad_space_names_the_field(change: dict[str, Any], field: str, words: str) -> None:
    found = problems(space_data(**change))
    assert field in found, found
    assert words in found[field]


def test_an_inline_scenario_reports_its_own_fields() -> None:
    found = problems(space_data(scenario={"version": 1, "name": "x", "intersection": "a_single_lane",
                                          "task": "left", "runs": 0}))
    assert "scenario.runs" in found


def test_a_point_of_the_space_is_the_nominal_scenario_with_its_values_one_run_and_its_seed() -> None:
    space = validate_space(space_data())
    spec = scenario_for(space, {"abnormal.overspeed.share": 0.3, "lights.phase": 4}, seed=77, name="p-1")
    nominal = load_scenario(NOMINAL)
    assert spec.name == "p-1" and spec.runs == 1 and spec.seed == 77
    assert spec.abnormal.overspeed is not None and spec.abnormal.overspeed.share == 0.3
    assert spec.lights.phase == 4 and spec.traffic == nominal.traffic and spec.ego == nominal.ego
    assert run_seeds(spec, 1) == run_seeds(spec.model_copy(update={"runs": 200}), 1)
    at_nominal = scenario_for(space, space.nominal_values(), seed=77, name="p-2")
    assert at_nominal.abnormal.overspeed is None  # an absent group stays absent at nominal
    assert at_nominal.model_copy(update={"name": nominal.name, "runs": nominal.runs, "seed": nominal.seed}) == nominal


def test_distance_and_what_is_off_nominal() -> None:
    space = validate_space(space_data())
    params = {"abnormal.overspeed.share": 0.25, "traffic.vehicles_per_hour": 400.0, "lights.phase": 4,
              "ego.start_distance_m": 35.0}
    # 0.25 of a 0.5 range, nominal traffic, another choice (1), 5 m of a 30 m range
    assert space.distance(params) == pytest.approx(0.5 + 0.0 + 1.0 + 5.0 / 30.0)
    assert space.off_nominal(params) == ["abnormal.overspeed.share", "lights.phase", "ego.start_distance_m"]
    assert space.distance(space.nominal_values()) == 0.0


def test_seeds_are_drawn_from_the_search_seed_within_the_range() -> None:
    space = validate_space(space_data(seed={"low": 100, "high": 110}))
    seeds = [draw_seed(space, 5, n) for n in range(50)]
    assert seeds == [draw_seed(space, 5, n) for n in range(50)]
    assert all(100 <= s <= 110 for s in seeds) and len(set(seeds)) > 5
    assert seeds != [draw_seed(space, 6, n) for n in range(50)]


def test_an_injection_moved_into_a_scenario_without_one_injects_what_the_space_proposes() -> None:
    space = validate_space(space_data(parameters=[
        {"path": "abnormal.injection.count", "low": 0, "high": 3},
        {"path": "abnormal.injection.arrive_s", "low": 0.0, "high": 20.0},
    ]))
    assert space.nominal_values() == {"abnormal.injection.count": 0, "abnormal.injection.arrive_s": 0.0}

    def injection(count: int, arrive_s: float) -> Any:
        return scenario_for(space, {"abnormal.injection.count": count, "abnormal.injection.arrive_s": arrive_s},
                            seed=1, name="t").abnormal.injection

    assert injection(0, 0.0) is None  # nominal: no injection at all
    assert (injection(2, 0.0).count, injection(2, 0.0).arrive_s) == (2, 0.0)
    assert (injection(0, 5.0).count, injection(0, 5.0).arrive_s) == (0, 5.0)  # the count proposed, not 1
    timing_only = validate_space(space_data(parameters=[
        {"path": "abnormal.injection.arrive_s", "low": 0.0, "high": 20.0}]))
    moved = scenario_for(timing_only, {"abnormal.injection.arrive_s": 5.0}, seed=1, name="t").abnormal.injection
    assert moved is not None and (moved.count, moved.arrive_s, moved.excess) == (1, 5.0, 0.0)


def test_a_pool_of_seeds_is_distinct_within_the_range_and_follows_the_search_seed() -> None:
    assert seed_pool(validate_space(space_data()), 5) is None  # no pool: each episode draws its own
    space = validate_space(space_data(seed={"low": 100, "high": 139, "pool": 16}))
    pool = seed_pool(space, 5)
    assert pool is not None and len(set(pool)) == 16 and pool == sorted(pool)
    assert all(100 <= s <= 139 for s in pool)
    assert seed_pool(space, 5) == pool and seed_pool(space, 6) != pool
    whole = validate_space(space_data(seed={"low": 7, "high": 9, "pool": 3}))
    assert seed_pool(whole, 1) == [7, 8, 9]  # a pool as large as the range is the range


def test_the_network_rejects_a_phase_it_lacks_and_a_time_beyond_the_phase(tmp_path: Path) -> None:
    space = validate_space(space_data(parameters=[
        {"path": "lights.phase", "choices": [0, 2, 40]},
        {"path": "lights.elapsed_s", "low": 0.0, "high": 20.0},
    ]))
    found = network_problems_of(space)
    texts = " | ".join(f"{f}: {m}" for f, m in found)
    assert any(f == "parameters.0" and "lights.phase" in m for f, m in found), texts
    assert any(f == "parameters.1" and "lights.elapsed_s" in m for f, m in found), texts
