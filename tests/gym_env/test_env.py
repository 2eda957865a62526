"""Crossroads-v0: the env checker, the same episodes as `crossroads run`, rewards, vector envs, SB3.

(The tests of ``crossroads.gym`` live in ``tests/gym_env``, not ``tests/gym``: pytest puts ``tests`` on
``sys.path``, where a ``gym`` folder would be what ``import gym`` finds; Stable-Baselines3 does that.)
"""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from gymnasium.utils.env_checker import check_env

import crossroads.gym  # noqa: F401  (registers Crossroads-v0)
from crossroads.constants import STATE_DIM
from crossroads.gym import CrossroadsEnv, RewardConfig
from crossroads.gym.observation import idc_view
from crossroads.gym.reward import step_reward
from crossroads.idc.rule_based import RuleBasedController
from crossroads.idc.state import PREVIEW_STATE_DIM

TINY = {  # a short, quiet left turn: an episode of ~80 steps
    "version": 1, "name": "tiny-left", "intersection": "a_single_lane", "task": "left",
    "traffic": {"vehicles_per_hour": 200, "cyclists_per_hour": 50, "pedestrians_per_hour": 50},
    "warmup_s": 5.0, "timeout_s": 12.0, "runs": 4, "seed": 7,
}
# gymnasium's advice, not failures: the action space is the paper's ranges (±0.4 rad/s, ±4.5 m/s³),
# and the raw IDC state has no finite bounds
ADVICE = ("symmetric and normalized space", "minimum value is -infinity", "maximum value is infinity")


@pytest.fixture
def scenario(tmp_path: Path) -> Path:
    path = tmp_path / "tiny-left.yaml"
    path.write_text(yaml.safe_dump(TINY))
    return path


def rule_episode_in_env(env: CrossroadsEnv, seed: int) -> tuple[list[float], dict, int]:
    """The rule controller drives through the environment (reading the world's full observation)."""
    controller = RuleBasedController()
    env.reset(seed=seed)
    controller.reset(env.candidates)
    rewards, steps = [], 0
    while True:
        action = controller.decide(env.observation).action
        _, reward, terminated, truncated, info = env.step(action)
        rewards.append(float(reward))
        steps += 1
        if terminated or truncated:
            return rewards, info, steps


@pytest.mark.parametrize("observation", ["box", "dict"])
def test_passes_gymnasiums_env_checker(scenario: Path, observation: str) -> None:
    env = gym.make("Crossroads-v0", scenario=str(scenario), observation=observation)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env.unwrapped, skip_render_check=True)
        other = [str(w.message) for w in caught if not any(a in str(w.message) for a in ADVICE)]
        assert other == []
        obs, info = env.reset(seed=5)
        assert env.observation_space.contains(obs)
        if observation == "dict":
            assert obs["candidates"].shape == (len(env.unwrapped.candidates), STATE_DIM)
            np.testing.assert_array_equal(obs["state"], obs["candidates"][obs["path"]])
        assert info["seed"] == 5 and info["candidates"] == len(env.unwrapped.candidates)
    finally:
        env.close()


def test_reset_seed_gives_the_episode_of_crossroads_run(tmp_path: Path) -> None:
    """Driven by the rule controller, reset(seed=N) ends as `crossroads run --seed N` (its own
    process), on nominal traffic where the seeds end differently."""
    scenario = tmp_path / "busy-left.yaml"
    scenario.write_text(yaml.safe_dump({**TINY, "name": "busy-left", "traffic": {}, "warmup_s": 30.0,
                                        "timeout_s": 25.0}))
    found = []
    env = CrossroadsEnv(scenario)
    try:
        for seed in (3, 5, 6):
            run = subprocess.run([sys.executable, "-m", "crossroads.cli", "run", str(scenario), "--seed",
                                  str(seed), "--json"], capture_output=True, text=True, check=True)
            expected = yaml.safe_load(run.stdout.strip().splitlines()[-1])
            rewards, info, steps = rule_episode_in_env(env, seed)
            assert (info["outcome"], steps, info["travel_time_s"]) == (
                expected["outcome"], expected["steps"], expected["travel_time_s"])
            assert all(np.isfinite(rewards))
            found.append((steps, info["travel_time_s"]))
    finally:
        env.close()
    assert len(set(found)) > 1  # the seeds do differ


def test_reward_is_the_negative_utility_with_the_penalty_and_the_outcome(scenario: Path) -> None:
    env = CrossroadsEnv(scenario, reward=RewardConfig(outcome_rewards={
        "passed": 7.0, "collision": -9.0, "red_light": -9.0, "off_road": -9.0, "timeout": -3.0, "error": -9.0}))
    try:
        obs, _ = env.reset(seed=3)
        action = np.array([0.1, -1.0])
        state = idc_view(env.observation, False, "nearest").state
        nxt, reward, terminated, truncated, info = env.step(action)
        parts = step_reward(env.reward_config, state, action, nxt.astype(np.float64), None)
        assert reward == pytest.approx(-(info["utility"] + info["penalty"]), rel=1e-5)
        assert info["utility"] == pytest.approx(parts.utility, rel=1e-5) and info["utility"] > 0.0
        assert info["outcome"] is None and not terminated and not truncated
        # the last step carries the outcome's reward, the outcome and (passed) the travel time
        rewards, last, _ = rule_episode_in_env(env, 3)
        assert last["outcome"] in ("passed", "timeout", "collision", "red_light", "off_road")
        assert last["outcome_reward"] == env.reward_config.outcome_rewards[last["outcome"]]
        assert rewards[-1] == pytest.approx(last["outcome_reward"] - last["utility"] - last["penalty"])
        assert (last["travel_time_s"] is not None) == (last["outcome"] == "passed")
    finally:
        env.close()


def test_a_catalogue_name_needs_a_task_and_options_are_checked() -> None:
    with pytest.raises(ValueError, match="give task= one of left, straight, right"):
        CrossroadsEnv("a_single_lane")
    with pytest.raises(ValueError, match="observation must be 'box' or 'dict'"):
        CrossroadsEnv("a_single_lane", "left", observation="image")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="path must be 'nearest' or a candidate index 0..0"):
        CrossroadsEnv("a_single_lane", "left", path=3)
    with pytest.raises(ValueError, match="outcome_rewards needs exactly.*missing: error"):
        RewardConfig(outcome_rewards={"passed": 1.0, "collision": -1.0, "red_light": -1.0,
                                      "off_road": -1.0, "timeout": 0.0})


def test_preview_states_and_seedless_resets_follow_the_scenario_seed(scenario: Path) -> None:
    first, second = CrossroadsEnv(scenario, preview=True), None
    try:
        obs, info = first.reset()
        assert obs.shape == (PREVIEW_STATE_DIM,) and obs.dtype == np.float32
        seeds = [info["seed"], first.reset()[1]["seed"]]
        first.close()
        second = CrossroadsEnv(scenario, preview=True)
        assert [second.reset()[1]["seed"], second.reset()[1]["seed"]] == seeds  # from the scenario's seed 7
        with pytest.raises(ValueError, match="action must be 2 finite numbers"):
            second.step(np.array([np.nan, 0.0]))
    finally:
        first.close()
        if second is not None:
            second.close()


@pytest.mark.slow
def test_runs_in_an_async_vector_env_of_sumo_processes(scenario: Path) -> None:
    """Two environments in two processes (libsumo: one simulation each) give the episodes one
    environment gives alone, seed by seed."""
    seeds, steps = [11, 12], 30
    actions = np.tile(np.array([[0.0, -0.5]], dtype=np.float32), (2, 1))
    vec = gym.vector.AsyncVectorEnv([lambda: gym.make("Crossroads-v0", scenario=str(scenario))] * 2)
    try:
        obs, _ = vec.reset(seed=seeds)
        trajectory = [obs]
        for _ in range(steps):
            obs, *_ = vec.step(actions)
            trajectory.append(obs)
    finally:
        vec.close()
    for k, seed in enumerate(seeds):
        single = CrossroadsEnv(scenario)
        try:
            obs, _ = single.reset(seed=seed)
            np.testing.assert_array_equal(obs, trajectory[0][k])
            for t in range(1, 6):  # the first steps (an episode may end and autoreset later)
                obs, *_ = single.step(actions[k])
                np.testing.assert_array_equal(obs, trajectory[t][k])
        finally:
            single.close()


@pytest.mark.slow
def test_stable_baselines3_ppo_runs_a_few_hundred_steps(scenario: Path, tmp_path: Path) -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    env = gym.make("Crossroads-v0", scenario=str(scenario))
    try:
        model = sb3.PPO("MlpPolicy", env, n_steps=128, batch_size=64, n_epochs=1, seed=0, device="cpu",
                        policy_kwargs={"net_arch": [32, 32]})
        model.learn(total_timesteps=256)
        model.save(tmp_path / "ppo")
        action, _ = model.predict(env.reset(seed=1)[0], deterministic=True)
        assert env.action_space.contains(action)
    finally:
        env.close()
