"""Python plugin policies: the example driver, checked decisions, batch worker processes and Ray."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

from crossroads.evaluation.batch import BatchRunner, create_batch_for
from crossroads.evaluation.episode import run_episode
from crossroads.policy.ref import PolicyError, parse_policy
from crossroads.evaluation.policies import load_controller
from crossroads.scenario.spec import load_scenario, run_seeds, to_world_config
from crossroads.sim.world import World
from crossroads.store import Store, crud, open_store

from support import REPO_ROOT

EXAMPLE = REPO_ROOT / "examples" / "plugin_driver"
REFERENCE = "py:cautious_driver:CautiousDriver"
TINY = {"version": 1, "name": "tiny-left", "intersection": "a_single_lane", "task": "left",
        "traffic": {"vehicles_per_hour": 200, "cyclists_per_hour": 50, "pedestrians_per_hour": 50},
        "warmup_s": 5.0, "timeout_s": 12.0, "runs": 3, "seed": 7}
FAULTY = '''
import numpy as np
from crossroads.idc.controller import Decision


class NoDecide:
    name = "no-decide"

    def reset(self, candidates):
        pass


class WrongType:
    def reset(self, candidates):
        pass

    def decide(self, observation):
        return np.zeros(2)


class BadPath:
    def reset(self, candidates):
        pass

    def decide(self, observation):
        return Decision(np.zeros(2), 5, "pass")


class NanAction:
    def reset(self, candidates):
        pass

    def decide(self, observation):
        return Decision(np.array([np.nan, 0.0]), 0, "pass")


def explodes():
    raise RuntimeError("no weights here")
'''


@pytest.fixture
def example_on_path(monkeypatch: pytest.MonkeyPatch) -> Path:
    """The example's directory on sys.path (inherited by spawned workers) and PYTHONPATH (Ray)."""
    monkeypatch.syspath_prepend(str(EXAMPLE))
    monkeypatch.setenv("PYTHONPATH", str(EXAMPLE))
    return EXAMPLE


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny-left.yaml"
    path.write_text(yaml.safe_dump(TINY))
    return path


@pytest.fixture
def store(tmp_path: Path) -> Iterator[Store]:
    opened = open_store(f"sqlite:///{tmp_path / 'results.db'}")
    yield opened
    opened.close()


def test_the_example_plugin_drives_episodes(example_on_path: Path, tiny: Path) -> None:
    controller = load_controller(parse_policy(REFERENCE))
    assert controller.name == "cautious"
    spec = load_scenario(tiny)
    with World(to_world_config(spec, base_dir=tiny.parent)) as world:
        results = [run_episode(world, controller, seed) for seed in run_seeds(spec, 2)]
    assert all(r.outcome in ("passed", "collision", "red_light", "off_road", "timeout") and r.steps > 10
               for r in results)


def test_a_faulty_plugin_fails_with_a_message_naming_the_problem(tmp_path: Path, tiny: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "faulty_drivers.py").write_text(FAULTY)
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(PolicyError, match=r"NoDecide\(\) returned a NoDecide without decide\(\)"):
        load_controller(parse_policy("py:faulty_drivers:NoDecide"))
    with pytest.raises(PolicyError, match=r"explodes\(\) raised RuntimeError: no weights here"):
        load_controller(parse_policy("py:faulty_drivers:explodes"))
    with pytest.raises(PolicyError, match="module 'faulty_drivers' has no callable 'Missing'"):
        load_controller(parse_policy("py:faulty_drivers:Missing"))
    spec = load_scenario(tiny)
    with World(to_world_config(spec, base_dir=tiny.parent)) as world:
        for factory, message in (("WrongType", "returned a ndarray; it must return a crossroads.idc.controller.Decision"),
                                 ("BadPath", r"path_index 5; it must be the index of a candidate path \(0..0\)"),
                                 ("NanAction", "action .*; it must be 2 finite numbers")):
            controller = load_controller(parse_policy(f"py:faulty_drivers:{factory}"))
            with pytest.raises(PolicyError, match=message):
                run_episode(world, controller, 1)


def test_a_batch_runs_a_plugin_in_its_worker_processes(example_on_path: Path, store: Store, tiny: Path,
                                                       tmp_path: Path) -> None:
    spec = load_scenario(tiny)
    batch_id = create_batch_for(store, spec=spec, policy=REFERENCE, runs=2, traces="none", base_dir=tiny.parent)
    result = BatchRunner(store, batch_id, workers=2, data_dir=tmp_path).run()
    assert result.status == "done" and result.recorded == 2 and result.errors == 0
    with store.session() as s:
        policy = crud.get_batch(session=s, batch_id=batch_id).policy
        assert (policy.kind, policy.name, policy.ref) == ("plugin", "CautiousDriver", REFERENCE)


@pytest.mark.slow
def test_ray_actors_load_a_plugin(example_on_path: Path, store: Store, tiny: Path, tmp_path: Path) -> None:
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)  # its workers inherit PYTHONPATH
    try:
        batch_id = create_batch_for(store, spec=load_scenario(tiny), policy=REFERENCE, runs=1, traces="none",
                                    base_dir=tiny.parent)
        result = BatchRunner(store, batch_id, workers=1, ray_address="local", data_dir=tmp_path).run()
    finally:
        ray.shutdown()
    assert result.recorded == 1 and result.errors == 0, result
