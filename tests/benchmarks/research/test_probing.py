"""The benchmarks' probes (benchmarks/research/probing.py): the receding-horizon optimum of the training model."""

from __future__ import annotations

import sys
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import torch
from support import REPO_ROOT

from crossroads.intersections import catalogue
from crossroads.rl.neural_nets import make_networks
from crossroads.sim.config import EgoStart, WorldConfig
from crossroads.sim.traffic import NO_TRAFFIC
from crossroads.sim.world import World

sys.path.insert(0, str(REPO_ROOT / "benchmarks" / "research"))
from probing import ModelOptimumController, timeout_cause  # noqa: E402


def ending_at(stood_s: float, past_stop_line: bool, ego_speed: float,
              others: list[tuple[float, float, float, str]]) -> tuple[SimpleNamespace, SimpleNamespace]:
    """The last observation's and true state's fields ``timeout_cause`` reads: the ego at the
    origin heading +y, and participants (x, y, speed, kind)."""
    x, y, speed, kind = (np.array(column) for column in zip(*others, strict=True)) if others else ([],) * 4
    snap = SimpleNamespace(x=np.asarray(x, float), y=np.asarray(y, float), speed=np.asarray(speed, float),
                           kind=np.asarray(kind, str))
    ego = np.array([0.0, 0.0, ego_speed, 0.0, np.pi / 2, 0.0, 0.0, 0.0])
    return (SimpleNamespace(front_vehicle_stopped_s=stood_s, past_stop_line=past_stop_line, ego=ego),
            SimpleNamespace(participants=snap))


def test_a_timeout_is_told_apart_by_what_held_the_ego() -> None:
    """The world's gridlocks (a vehicle ahead standing ≥ 30 s) apart from shorter queues, and without
    a standing leader, where the ego was and the closest participant in its way (not one behind or
    beside it, nor one beyond 10 m)."""
    assert timeout_cause(*ending_at(45.0, False, 0.0, [])) == "behind a vehicle standing ≥ 30 s"
    assert timeout_cause(*ending_at(4.0, False, 0.0, [])) == "behind a vehicle standing < 30 s"
    walkers = [(0.5, 6.0, 0.0, "vehicle"), (-1.0, 4.0, 1.2, "pedestrian"), (0.0, -5.0, 0.0, "vehicle")]
    assert timeout_cause(*ending_at(0.0, True, 0.1, walkers)) == "inside the junction, ego standing, a moving pedestrian ahead"
    aside = [(3.0, 4.0, 0.0, "vehicle"), (0.0, 12.0, 0.0, "vehicle"), (0.0, -3.0, 0.0, "cyclist")]
    assert timeout_cause(*ending_at(0.0, False, 2.0, aside)) == "before the stop line, ego moving, nothing within 10 m ahead"
    assert timeout_cause(*ending_at(0.0, False, 0.0, [])) == "before the stop line, ego standing, nothing within 10 m ahead"


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
