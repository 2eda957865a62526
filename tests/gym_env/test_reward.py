"""The reward's penalties are exactly idc.constraints' (their shortcuts skip only exact zeros)."""

from __future__ import annotations

import numpy as np
import pytest

from crossroads.evaluation.onnx_policy import trial_states
from crossroads.gym.reward import RewardConfig, road_penalty, safety_penalty, step_reward
from crossroads.idc.constraints import penalty, road_constraints, safety_constraints
from crossroads.idc.state import DPHI, DY, OTHERS, PX, PY
from crossroads.idc.utility import utility


def states(n: int, seed: int = 0) -> np.ndarray:
    """Padded states with participants strewn around the ego (some overlapping it, most not) and
    tracking errors on both sides of the road bound."""
    rng = np.random.default_rng(seed)
    out = np.repeat(trial_states(108, 1), n, axis=0)
    out[:, PX], out[:, PY] = rng.uniform(-50, 50, n), rng.uniform(-50, 50, n)
    others = out[:, OTHERS].reshape(n, 16, 6)
    placed = rng.random((n, 16)) < 0.5
    others[..., 0] = np.where(placed, out[:, PX, None] + rng.normal(0, 6, (n, 16)), others[..., 0])
    others[..., 1] = np.where(placed, out[:, PY, None] + rng.normal(0, 6, (n, 16)), others[..., 1])
    others[..., 3] = np.where(placed, rng.uniform(-np.pi, np.pi, (n, 16)), others[..., 3])
    others[..., 4] = np.where(placed, rng.uniform(0.3, 12.0, (n, 16)), others[..., 4])
    others[..., 5] = np.where(placed, rng.uniform(0.4, 2.6, (n, 16)), others[..., 5])
    out[:, OTHERS] = others.reshape(n, -1)
    out[:, DY], out[:, DPHI] = rng.normal(0, 1.5, n), rng.normal(0, 0.4, n)
    return out


def test_the_penalties_equal_the_constraints_penalties() -> None:
    batch = states(800)
    safety = [safety_penalty(s) for s in batch]
    road = [road_penalty(s) for s in batch]
    assert safety == [float(penalty(safety_constraints(s))) for s in batch]
    assert road == [float(penalty(road_constraints(s))) for s in batch]
    assert 0 < sum(p > 0 for p in safety) < len(batch) and 0 < sum(p > 0 for p in road) < len(batch)


def test_step_reward_adds_the_parts() -> None:
    s, nxt = states(2, seed=4)
    action = np.array([0.7, -9.0])  # beyond the ranges: the reward charges the applied (clipped) action
    parts = step_reward(RewardConfig(penalty_weight=2.0), s, action, nxt, "collision")
    assert parts.utility == pytest.approx(float(utility(s, np.array([0.4, -4.5]))[0]))
    assert parts.penalty == pytest.approx(2.0 * (safety_penalty(nxt) + road_penalty(nxt)))
    assert parts.total == pytest.approx(-100.0 - parts.utility - parts.penalty)
    with pytest.raises(ValueError, match="penalty_weight must be a finite number >= 0"):
        RewardConfig(penalty_weight=-1.0)
