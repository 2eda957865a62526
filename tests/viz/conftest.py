"""Fixtures of the 3D view's tests: one real episode's trace (SUMO through libsumo, the rule
controller), recorded once per module."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from crossroads.evaluation.episode import run_episode
from crossroads.evaluation.trace import Trace, TraceRecorder
from crossroads.idc.rule_based import RuleBasedController
from crossroads.scenario.spec import load_scenario, to_world_config
from crossroads.sim.world import World
from support import REPO_ROOT

SCENARIO = REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-left.yaml"


@pytest.fixture(scope="module")
def trace_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    spec = load_scenario(SCENARIO)
    config = replace(to_world_config(spec), warmup_s=15.0, timeout_s=6.0)
    recorder = TraceRecorder()
    with World(config) as world:
        run_episode(world, RuleBasedController(), seed=3, recorder=recorder, scenario_name=spec.name)
    path = tmp_path_factory.mktemp("traces") / "a.trace.npz"
    recorder.trace().save(path)
    return path


@pytest.fixture(scope="module")
def trace(trace_file: Path) -> Trace:
    return Trace.load(trace_file)
