"""The benchmarks' probes (benchmarks/probing.py): the receding-horizon optimum of the training model."""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
import torch
from support import REPO_ROOT

from crossroads.network import catalogue
from crossroads.rl.networks import make_networks
from crossroads.sim.config import EgoStart, WorldConfig
from crossroads.sim.traffic import NO_TRAFFIC
from crossroads.sim.world import World

sys.path.insert(0, str(REPO_ROOT / "benchmarks"))
from probing import ModelOptimumController  # noqa: E402


def test_the_model_optimum_tracks_an_empty_straight_road_an_untrained_policy_does_not() -> None:
    """Where the policy is untrained, only the optimisation of the model's own J_π can keep the ego on
    the path at the reference speed: the controller must really optimise, not echo the policy."""
    torch.manual_seed(0)
    nets = make_networks("dpg", hidden_layers=5, hidden_units=256)
    base = WorldConfig(net_file=catalogue.build("c_three_lane"), task="straight", demand=NO_TRAFFIC, warmup_s=1.0)
    with World(base) as probe:
        path = probe.candidates[1]
    config = replace(base, ego_start=EgoStart(entrance_lane=path.entrance_lane))

    def drive(controller: object, steps: int) -> tuple[float, float]:
        with World(config) as world:
            obs = world.reset(0)
            controller.reset([path])  # type: ignore[attr-defined]
            lateral, speed_error = [], []
            for _ in range(steps):
                obs, outcome = world.step(controller.decide(obs).action)  # type: ignore[attr-defined]
                assert outcome is None
                here = path.project(obs.ego[0], obs.ego[1])
                lateral.append(abs(here.lateral_m))
                speed_error.append(abs(obs.ego[2] - path.reference_at(here.s_m, "pass")[3]))
        return float(np.max(lateral)), float(np.max(speed_error))

    optimum = ModelOptimumController(nets.policy, nets.value, steps=10, first_steps=60)
    lateral, speed_error = drive(optimum, 15)
    assert lateral < 0.02 and speed_error < 0.2  # measured: 0.003 m, 0.04 m/s after 15 steps

    from crossroads.idc.decision import IdcController

    lateral_policy, speed_policy = drive(IdcController(nets.policy, nets.value), 15)
    assert lateral_policy > 2 * lateral or speed_policy > 2 * speed_error
