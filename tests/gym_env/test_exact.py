"""The environment's fast paths give the definitions' numbers, bit for bit: the observation is the
IDC state as the IDC controller builds it, the reward the utility and the penalties of
``idc.utility`` and ``idc.constraints`` computed in full (no screening, no Python-float shortcuts)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from crossroads.constants import JERK_MAX, STATE_DIM, STEER_RATE_MAX
from crossroads.gym import CrossroadsEnv, RewardConfig
from crossroads.gym.reward import safety_penalty, step_reward
from crossroads.idc.constraints import (
    EGO_CIRCLE_OFFSET_M,
    EGO_RADIUS_M,
    SAFETY_MARGIN_M,
    penalty,
    road_constraints,
    safety_constraints,
)
from crossroads.idc.lights import choose_speed_mode
from crossroads.idc.rule_based import RuleBasedController
from crossroads.idc.state import DX, DY, OTHERS, PHI, PX, PY, build_states, select_others
from crossroads.idc.utility import utility
from crossroads.sim.observation import Observation

BUSY = {  # nominal traffic on a left turn, short: ~200 steps among queued cars and crossing traffic
    "version": 1, "name": "busy-left", "intersection": "a_single_lane", "task": "left",
    "warmup_s": 30.0, "timeout_s": 20.0, "runs": 2, "seed": 7,
}


def reference_states(obs: Observation) -> tuple[np.ndarray, int]:
    """Every candidate's state as ``IdcController`` builds it and the nearest candidate."""
    mode = choose_speed_mode(
        front_vehicle_stopped_s=obs.front_vehicle_stopped_s, past_stop_line=obs.past_stop_line,
        light=obs.light.light, distance_to_stop_line_m=obs.distance_to_stop_line_m,
        speed_mps=float(obs.ego[2]), yellow_remaining_s=obs.light.remaining_s)
    others = select_others(obs.ego, obs.perceived.observations, obs.perceived.kinds)
    states = build_states(obs.ego, others, obs.candidates, mode, False)
    return states, int(np.argmin(np.hypot(states[:, DX], states[:, DY])))


def reference_reward(config: RewardConfig, state: np.ndarray, action: np.ndarray, nxt: np.ndarray,
                     outcome: str | None) -> tuple[float, float, float]:
    """(reward, utility, weighted penalty) from the definitions, every constraint computed."""
    applied = np.clip(np.asarray(action, dtype=np.float64), [-STEER_RATE_MAX, -JERK_MAX], [STEER_RATE_MAX, JERK_MAX])
    l_value = float(utility(state[:STATE_DIM], applied)[0])
    phi = float(penalty(safety_constraints(nxt[:STATE_DIM]))) + float(penalty(road_constraints(nxt[:STATE_DIM])))
    bonus = 0.0 if outcome is None else config.outcome_rewards[outcome]
    weighted = config.penalty_weight * phi
    return bonus - l_value - weighted, l_value, weighted


@pytest.mark.parametrize("observation", ["dict", "box"])
def test_a_seeded_episode_observes_and_rewards_as_the_definitions(tmp_path: Path, observation: str) -> None:
    """Every candidate's state (dict), or the tracked one's alone (box: built by itself), the
    tracked path and the reward, step by step, as the definitions give them."""
    scenario = tmp_path / "busy-left.yaml"
    scenario.write_text(yaml.safe_dump(BUSY))
    env = CrossroadsEnv(scenario, observation=observation)
    config = env.reward_config
    try:
        for seed in (3, 5):
            obs, info = env.reset(seed=seed)
            states, path = reference_states(env.observation)
            check_observation(obs, info, states, path)
            controller = RuleBasedController()
            controller.reset(env.candidates)
            steps = 0
            while True:
                before = states[path]
                action = controller.decide(env.observation).action
                # a swerve now and then, beyond the action's ranges: the reward charges the clipped one
                if steps % 7 == 3:
                    action = np.array([0.9, -7.0]) if steps % 2 else np.array([-0.55, 6.0])
                obs, reward, terminated, truncated, info = env.step(action)
                states, path = reference_states(env.observation)
                check_observation(obs, info, states, path)
                total, l_value, weighted = reference_reward(config, before, action, states[path], info["outcome"])
                assert (reward, info["utility"], info["penalty"]) == (total, l_value, weighted)
                steps += 1
                if terminated or truncated:
                    break
            assert steps > 50
    finally:
        env.close()


def check_observation(obs: Any, info: dict[str, Any], states: np.ndarray, path: int) -> None:
    """``obs`` (box or dict) and ``info`` observe ``states`` (every candidate's) tracking ``path``."""
    assert info["path"] == path
    if isinstance(obs, dict):
        np.testing.assert_array_equal(obs["candidates"], states.astype(np.float32))
        assert obs["path"] == path
        obs = obs["state"]
    assert obs.dtype == np.float32 and obs.tobytes() == states[path].astype(np.float32).tobytes()


def near_miss_states(gaps: list[float], seed: int = 0) -> np.ndarray:
    """States whose deepest safety constraint is g = gap (± rounding): a car, a cyclist or a
    pedestrian placed so that one of its circles is that far inside (gap > 0) or outside (< 0) the
    margin of the ego's front circle, the other slots padded far away."""
    rng = np.random.default_rng(seed)
    out = []
    for gap in gaps:
        state = np.zeros(STATE_DIM)
        state[PX], state[PY], state[PHI] = rng.uniform(-200, 200, 2).tolist() + [rng.uniform(-np.pi, np.pi)]
        others = np.tile([state[PX] - 300.0, state[PY], 0.0, 0.0, 4.8, 1.8], (16, 1))
        slot = int(rng.choice([0, 9, 13]))  # a vehicle, a cyclist, a pedestrian
        length, width = (4.6, 1.9) if slot < 12 else (0.5, 0.6)
        radius = width / 2.0 if slot < 12 else float(np.sqrt(length**2 / 4 + width**2 / 4 + 1e-12))
        offset = (length - width) / 2.0 if slot < 12 else 0.0
        front = (state[PX] + EGO_CIRCLE_OFFSET_M * np.cos(state[PHI]), state[PY] + EGO_CIRCLE_OFFSET_M * np.sin(state[PHI]))
        bearing, heading = rng.uniform(-np.pi, np.pi, 2)
        centre = EGO_RADIUS_M + radius + SAFETY_MARGIN_M - gap  # the circles' centres this far apart
        circle = (front[0] + centre * np.cos(bearing), front[1] + centre * np.sin(bearing))
        others[slot] = [circle[0] + offset * np.cos(heading), circle[1] + offset * np.sin(heading), 3.0, heading,
                        length, width]  # its front circle (+offset along its heading) is the one placed
        state[OTHERS] = others.reshape(-1)
        out.append(state)
    return np.array(out)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_safety_penalty_is_exact_at_the_constraints_boundary(seed: int) -> None:
    gaps = [s * m for m in (1e-12, 1e-9, 1e-7, 1e-6, 1e-5, 2e-5, 1e-3, 0.1) for s in (1.0, -1.0)] * 10
    batch = near_miss_states(gaps, seed)
    computed = [safety_penalty(s) for s in batch]
    assert computed == [float(penalty(safety_constraints(s))) for s in batch]
    assert sum(p > 0 for p in computed) >= 0.4 * len(gaps)  # the placed ones inside count


def test_step_reward_takes_float32_states_as_float64() -> None:
    s, nxt = near_miss_states([0.2, -0.2], seed=5)
    action = np.array([0.1, -1.0], dtype=np.float32)
    parts = step_reward(RewardConfig(), s.astype(np.float32), action, nxt.astype(np.float32), None)
    total, l_value, weighted = reference_reward(RewardConfig(), s.astype(np.float32).astype(np.float64),
                                                action, nxt.astype(np.float32).astype(np.float64), None)
    assert (parts.total, parts.utility, parts.penalty) == (total, l_value, weighted)
