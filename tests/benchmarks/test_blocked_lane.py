"""Runs no driver can pass (benchmarks/blocked_lane.py): a vehicle across every candidate path that
never moves."""

from __future__ import annotations

import sys

import numpy as np
from support import REPO_ROOT

from crossroads.evaluation.scenario import load_scenario, to_world_config
from crossroads.sim.world import World

sys.path.insert(0, str(REPO_ROOT / "benchmarks"))
from blocked_lane import StandingDriver, bars_every_path, drive  # noqa: E402

NOMINAL_LEFT = REPO_ROOT / "scenarios" / "nominal" / "c_three_lane-left.yaml"
# a seed of the nominal left turn whose queue ahead of the ego never moves in 60 s (measured with
# the rule controller, APG + shield and the standing driver alike, docs/tried/world.md)
HELD_SEED = 556745865


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


def test_a_standing_ego_times_out_behind_a_queue_that_never_moves() -> None:
    """Seed 556745865: with the ego standing far back the vehicle across its paths stands all 60 s,
    in SUMO, the world's own gridlock."""
    spec = load_scenario(NOMINAL_LEFT)
    with World(to_world_config(spec, NOMINAL_LEFT.parent)) as world:
        end = drive(world, StandingDriver(), HELD_SEED)
    assert end.outcome == "timeout" and end.held_from_start
    assert end.blocker_last_moved_s == -np.inf and end.blocker_ahead_m is not None and end.blocker_ahead_m > 10.0
