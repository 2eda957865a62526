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

from crossroads.idc.controller import Decision
from crossroads.idc.decision import IdcController
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
