"""Sampling rounds in the SUMO world: states lie near the path they are recorded with, the demand
scale and the rule share act, and a round is a function of (seed, worker, round, weights)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from crossroads.rl.config import TrainConfig
from crossroads.rl.sampler import EpisodeSampler, PathSet, WorkerSpec

# left turns of the two-lane intersection: two candidates from the same entrance lane
INTERSECTION = "b_two_lane"
CONFIG = TrainConfig(intersections=(INTERSECTION,), tasks=("left",), workers=0, hidden_units=32,
                     max_episode_steps=80, warmup_s=5.0, rule_rounds=0, rule_share=1.0)


@pytest.fixture(scope="module")
def left_paths() -> PathSet:
    return PathSet.build((INTERSECTION,), ("left",))


def _sampler(paths: PathSet, **changes: object) -> EpisodeSampler:
    return EpisodeSampler(WorkerSpec(replace(CONFIG, **changes), paths.keys), worker_id=0)


def test_rule_driven_states_lie_near_their_own_path(left_paths: PathSet) -> None:
    """The rule driver follows the drawn path, so the recorded path index is the one driven (both
    candidates start on the same lane: a driver keeping to the first would end metres off the second)."""
    assert len(left_paths.candidates) == 2
    sampler = _sampler(left_paths, max_episode_steps=120)
    seen = set()
    for round_index in range(6):
        samples = sampler.round(round_index, None)
        assert len(samples.ego) > 10
        seen.update(int(p) for p in samples.path)
        for ego, path in zip(samples.ego, samples.path):
            lateral = left_paths.candidates[int(path)].project(float(ego[0]), float(ego[1])).lateral_m
            assert abs(lateral) < 1.5, (round_index, int(path), lateral)
    assert seen == {0, 1}


def test_zero_demand_scale_gives_an_empty_scene(left_paths: PathSet) -> None:
    rng = np.random.default_rng(0)
    world_cfg, *_ = _sampler(left_paths, demand_scale=(0.0, 0.0)).episode_config(rng)
    assert world_cfg.demand.vehicles_per_hour == 0.0 and world_cfg.demand.pedestrians_per_hour == 0.0
    world_cfg, *_ = _sampler(left_paths, demand_scale=(2.0, 2.0)).episode_config(np.random.default_rng(0))
    assert world_cfg.demand.vehicles_per_hour == pytest.approx(2 * 400.0)


def test_empty_share_empties_that_share_of_the_episodes_and_nothing_else(left_paths: PathSet) -> None:
    """About ``empty_share`` of the episodes have no traffic; the others keep their drawn demand, and
    the world, the light and the ego's start are drawn before the coin, so they stay as without it."""
    def demands(**changes: object) -> list[float]:
        sampler = _sampler(left_paths, demand_scale=(1.0, 1.0), **changes)
        return [sampler.episode_config(np.random.default_rng([0, 0, r]))[0].demand.vehicles_per_hour
                for r in range(400)]

    shared = demands(empty_share=0.25)
    empty = sum(d == 0.0 for d in shared)
    assert 70 <= empty <= 130  # 100 expected
    assert all(d == pytest.approx(400.0) for d in shared if d != 0.0)
    assert all(d == pytest.approx(400.0) for d in demands(empty_share=0.0))
    for r in range(20):
        with_coin = _sampler(left_paths, empty_share=0.5).episode_config(np.random.default_rng([0, 0, r]))
        without = _sampler(left_paths, empty_share=0.0).episode_config(np.random.default_rng([0, 0, r]))
        assert replace(with_coin[0], demand=without[0].demand) == without[0] and with_coin[1:] == without[1:]


def test_standing_car_copies_follow_the_episode_and_leave_it_unchanged(left_paths: PathSet) -> None:
    """A round returns its episode's states, then the copies with a standing car (rl.augment); the
    episode is the same as without them."""
    plain = _sampler(left_paths, standing_car_share=0.0).round(2, None)
    both = _sampler(left_paths, standing_car_share=0.5).round(2, None)
    n = len(plain.ego)
    assert n < len(both.ego) < 2 * n
    np.testing.assert_array_equal(both.ego[:n], plain.ego)
    np.testing.assert_array_equal(both.others[:n], plain.others)
    vehicles = both.others[n:, :8]  # each copy holds the standing 5.0 × 1.8 m car among its vehicles
    car = (vehicles[..., 2] == 0.0) & (vehicles[..., 4] == 5.0) & (np.abs(vehicles[..., 5] - 1.8) < 1e-6)
    assert np.all(car.any(axis=1))


def test_a_round_is_repeatable(left_paths: PathSet) -> None:
    a = _sampler(left_paths).round(3, None)
    b = _sampler(left_paths).round(3, None)
    np.testing.assert_array_equal(a.ego, b.ego)
    np.testing.assert_array_equal(a.others, b.others)


@pytest.mark.parametrize(("field", "value", "message"), [
    ("rule_share", 1.5, "rule_share"), ("empty_share", -0.1, "empty_share"),
    ("standing_car_share", 2.0, "standing_car_share"),
    ("standing_car_gap_m", (3.0, 1.0), "standing_car_gap_m"), ("demand_scale", (1.0, 0.5), "demand_scale"),
    ("demand_scale", (-1.0, 0.5), "demand_scale")])
def test_bad_sampling_options_are_named(field: str, value: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        replace(CONFIG, **{field: value})


ORPHAN_SCRIPT = """
import sys, time
from crossroads.rl.config import TrainConfig
from crossroads.rl.sampler import PathSet, ProcessSampler, WorkerSpec
config = TrainConfig(intersections=("a_single_lane",), tasks=("left",), workers=1)
sampler = ProcessSampler(WorkerSpec(config, PathSet.build(config.intersections, config.tasks).keys), 1)
print(sampler._procs[0].pid, flush=True)
time.sleep(120)
"""


@pytest.mark.slow
def test_workers_of_a_killed_learner_exit() -> None:
    """A learner killed by a signal cannot tell its workers to stop; they notice and leave."""
    import os
    import signal
    import subprocess
    import sys
    import time

    learner = subprocess.Popen([sys.executable, "-c", ORPHAN_SCRIPT], stdout=subprocess.PIPE, text=True)
    try:
        worker = int(learner.stdout.readline())  # type: ignore[union-attr]
        os.kill(learner.pid, signal.SIGKILL)
        learner.wait()
        deadline = time.monotonic() + 60.0  # the worker may still be importing torch and SUMO
        while time.monotonic() < deadline:
            try:
                os.kill(worker, 0)
            except ProcessLookupError:
                return
            with open(f"/proc/{worker}/stat") as f:  # a zombie has exited: gone for our purpose
                if f.read().split(")")[-1].split()[0] == "Z":
                    return
            time.sleep(0.5)
        os.kill(worker, signal.SIGKILL)
        raise AssertionError("the sampling worker outlived its learner by 60 s")
    finally:
        if learner.poll() is None:
            learner.kill()
