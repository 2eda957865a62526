"""Every scenario shipped in scenarios/ loads and converts to a WorldConfig."""

from __future__ import annotations

from pathlib import Path

import pytest

from crossroads.constants import EVALUATION_RUNS, OVERSPEED_LEVELS, OVERSPEED_SHARE, ROUNDING_LEVELS
from crossroads.scenario.spec import load_scenarios, to_world_config
from crossroads.intersections.catalogue import list_intersections
from crossroads.sim.config import WorldConfig
from support import REPO_ROOT

SCENARIO_DIRS = ("nominal", "paper", "regression")
FILES = sorted(p for d in SCENARIO_DIRS for p in (REPO_ROOT / "scenarios" / d).glob("*.yaml"))


@pytest.mark.parametrize("path", FILES, ids=[f"{p.parent.name}/{p.name}" for p in FILES])
def test_scenario_file_converts(path: Path) -> None:
    [(loaded_path, spec)] = load_scenarios(path)
    assert loaded_path == path
    assert spec.name == path.stem  # the file is named after the scenario
    assert spec.description.strip()
    config = to_world_config(spec, path.parent)
    assert isinstance(config, WorldConfig)
    assert config.net_file.is_file() and config.task == spec.task


def test_nominal_covers_every_intersection_and_task() -> None:
    specs = [s for _, s in load_scenarios(REPO_ROOT / "scenarios" / "nominal")]
    assert {(s.intersection, s.task) for s in specs} == {
        (name, task) for name in list_intersections() for task in ("left", "straight", "right")}
    assert len(specs) == 18
    for s in specs:
        assert (s.lights.phase, s.lights.elapsed_s) == (0, 0.0)  # green at start
        assert (s.traffic.vehicles_per_hour, s.traffic.cyclists_per_hour,
                s.traffic.pedestrians_per_hour) == (400, 100, 100)
        assert s.abnormal.overspeed is None and s.abnormal.rounding is None
        assert s.runs == EVALUATION_RUNS


def test_paper_cases_match_spec_section_8() -> None:
    specs = {s.name: s for _, s in load_scenarios(REPO_ROOT / "scenarios" / "paper")}
    assert len(specs) == 6
    for level in OVERSPEED_LEVELS:
        s = specs[f"overspeed-{round(level * 100)}"]
        assert s.abnormal.overspeed is not None and s.abnormal.rounding is None
        assert (s.abnormal.overspeed.share, s.abnormal.overspeed.excess) == (OVERSPEED_SHARE, level)
    for level in ROUNDING_LEVELS:
        s = specs[f"rounding-{round(level * 100)}"]
        assert s.abnormal.rounding is not None and s.abnormal.overspeed is None
        assert s.abnormal.rounding.share == level
    for s in specs.values():
        assert s.task == "left" and s.intersection == "c_three_lane" and s.runs == 200
        assert (s.lights.phase, s.lights.elapsed_s) == (0, 0.0)
        assert "row" in s.description
    assert len({s.seed for s in specs.values()}) == 1  # every case meets the same departures
