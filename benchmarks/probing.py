"""What the benchmarks that probe a trained model inside seeded episodes share.

``failure_modes.py``, ``adversary_strength.py`` and ``value_ordering.py`` all take a scenario and a
model, drive the scenario's seeded episodes (the seeds of ``crossroads evaluate``) with the model's
online decision, and look at some of the states on the way.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from crossroads.constants import JERK_MAX, PENALTY_RHO, STEER_RATE_MAX
from crossroads.idc.controller import Decision
from crossroads.idc.decision import IdcController
from crossroads.rl.model import IDCModel, Rollout, StateBatch
from crossroads.sim.world import Observation, World

HORIZON = 25  # the paper's T, the training model's rollout length


def ego_frame(ego: np.ndarray, x: Any, y: Any) -> tuple[Any, Any]:
    """(along, across) [m] of the points (x, y) in the frame of ``ego`` (its position and heading φ)."""
    c, s = math.cos(float(ego[4])), math.sin(float(ego[4]))
    dx, dy = x - ego[0], y - ego[1]
    return c * dx + s * dy, -s * dx + c * dy


def model_parser(description: str, runs: int) -> argparse.ArgumentParser:
    """A parser with the arguments every probing benchmark takes: scenario, --policy, --runs."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("scenario", type=Path)
    parser.add_argument("--policy", required=True, help="a trained model (.pt)")
    parser.add_argument("--runs", type=int, default=runs, help="seeded episodes of the scenario")
    return parser


def probed_states(world: World, controller: IdcController, seeds: Sequence[int],
                  every: int) -> Iterator[tuple[Observation, Decision]]:
    """Drive each seeded episode to its end; yield (observation, decision) every ``every`` steps."""
    for seed in seeds:
        obs = world.reset(seed)
        controller.reset(world.candidates)
        outcome, step = None, 0
        while outcome is None:
            decision = controller.decide(obs)
            if step % every == 0:
                yield obs, decision
            obs, outcome = world.step(decision.action)
            step += 1


def open_loop_optimum(model: IDCModel, batch: StateBatch, steps: int = 250, lr: float = 0.05) -> Rollout:
    """The model's own best plan from each state: Adam on the T actions of every state alone (no
    policy), minimising J_π = J_track + ρ J_safe with ξ ≡ 0; the actions go through tanh into their
    ranges so every step stays feasible. Zero actions to start. Its rollout (no gradient)."""
    scale = torch.tensor([STEER_RATE_MAX, JERK_MAX], dtype=batch.ego.dtype)
    raw = torch.zeros(batch.ego.shape[0], HORIZON, 2, dtype=batch.ego.dtype, requires_grad=True)
    optimiser = torch.optim.Adam([raw], lr=lr)

    def plan(_s: torch.Tensor, i: int) -> torch.Tensor:
        return torch.tanh(raw[:, i]) * scale

    for _ in range(steps):
        out = model.rollout(batch, plan, None, HORIZON)
        optimiser.zero_grad()
        (out.j_track + PENALTY_RHO * out.j_safe).sum().backward()  # states are independent: a sum
        optimiser.step()
    with torch.no_grad():
        return model.rollout(batch, plan, None, HORIZON)
