"""Runs no driver can pass (benchmarks/blocked_lane.py): a vehicle across every candidate path that
never moves."""

from __future__ import annotations

import sys
from dataclasses import replace

import libsumo
import numpy as np
from support import REPO_ROOT

from crossroads.scenario.spec import load_scenario, to_world_config
from crossroads.intersections import catalogue
from crossroads.sim.config import WorldConfig
from crossroads.sim.traffic import NO_TRAFFIC
from crossroads.sim.world import World

sys.path.insert(0, str(REPO_ROOT / "benchmarks"))
from blocked_lane import StandingDriver, bars_every_path, drive  # noqa: E402

NOMINAL_LEFT = REPO_ROOT / "scenarios" / "nominal" / "c_three_lane-left.yaml"


def test_a_vehicle_bars_every_path_only_where_the_paths_have_not_parted() -> None:
    """On the entrance lane every left-turn path runs through a car's body; on one path's exit lane,
    or a lane to the side, not all of them do."""
    spec = load_scenario(NOMINAL_LEFT)
    with World(to_world_config(spec, NOMINAL_LEFT.parent)) as world:
        paths = world.candidates
        assert len(paths) == 3
        start = paths[0].points[10]
        assert bars_every_path(float(start[0]), float(start[1]), 1.8, paths)
        assert not bars_every_path(float(start[0]) + 3.5, float(start[1]), 1.8, paths)  # the next lane
        end = paths[0].points[-1]
        assert not bars_every_path(float(end[0]), float(end[1]), 1.8, paths)


class _StandingBehindABlocker(StandingDriver):
    """The standing driver, with a car put 8 m before the ego's stop line on its first step that
    never moves: a scene built to be held from the start."""

    def __init__(self, world: World) -> None:
        self.world = world

    def decide(self, observation):  # noqa: ANN001, ANN201
        session, lane = self.world.session, self.world.start_lane
        if "blocker" not in session.vehicle_ids and observation.time_s < 0.05:
            exit_edge = self.world.junction.lanes[self.world.candidates[0].exit_lane].edge_id
            libsumo.route.add(f"blocker{self.world.episode_seed}", [lane.edge_id, exit_edge])
            libsumo.vehicle.add("blocker", f"blocker{self.world.episode_seed}", typeID="car", depart="now",
                                departLane=str(lane.index), departPos=str(lane.length_m - 8.0), departSpeed="0")
        elif "blocker" in session.vehicle_ids:
            session.set_speed("blocker", 0.0)
        return super().decide(observation)


def test_a_standing_ego_times_out_behind_a_vehicle_that_never_moves() -> None:
    config = replace(WorldConfig(net_file=catalogue.build("c_three_lane"), task="left"),
                     demand=NO_TRAFFIC, warmup_s=0.0, timeout_s=12.0)
    with World(config) as world:
        end = drive(world, _StandingBehindABlocker(world), seed=3)
    assert end.outcome == "timeout" and end.held_from_start and end.blocker == "blocker"
    assert end.blocker_last_moved_s == -np.inf and end.blocker_ahead_m is not None and end.blocker_ahead_m > 10.0
