"""Runs the world lost: a timeout behind a participant standing across every candidate path the
whole episode is recorded as ``blocked_by``; one behind a participant that moved is not."""

from __future__ import annotations

import libsumo
import numpy as np
import pytest

from crossroads.idc.rule_based import RuleBasedController
from crossroads.intersections import catalogue
from crossroads.sim.blocking import bars_every_path, held_whole_episode, nearest_barrier
from crossroads.sim.config import WorldConfig
from crossroads.sim.traffic import NO_TRAFFIC
from crossroads.sim.world import World


@pytest.fixture(scope="module")
def world() -> World:
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", demand=NO_TRAFFIC,
                         warmup_s=0.0, timeout_s=12.0, perception_noise=False)
    with World(config) as w:
        yield w


def _episode_behind_a_blocker(world: World, seed: int, *, release_at_s: float | None) -> object:
    """The rule controller drives up to a car standing in the ego's lane 8 m before the stop line
    (released at ``release_at_s`` to drive on, or never)."""
    controller = RuleBasedController()
    obs = world.reset(seed)
    controller.reset(world.candidates)
    lane = world.start_lane
    libsumo.route.add(f"blocker_route{seed}", [world.approach.incoming_edge,
                                               world.junction.lanes[world.candidates[0].exit_lane].edge_id])
    libsumo.vehicle.add("blocker", f"blocker_route{seed}", typeID="car", depart="now",
                        departLane=str(lane.index), departPos=str(lane.length_m - 8.0), departSpeed="0")
    outcome = None
    while outcome is None:
        obs, outcome = world.step(controller.decide(obs).action)
        if "blocker" in world.session.vehicle_ids:
            stopped = release_at_s is None or obs.time_s < release_at_s
            world.session.set_speed("blocker", 0.0 if stopped else -1.0)
    return outcome


def test_a_lane_held_the_whole_episode_is_blocked_by_the_world(world: World) -> None:
    outcome = _episode_behind_a_blocker(world, 1, release_at_s=None)
    assert outcome.kind == "timeout"
    assert outcome.blocked_by is not None
    assert outcome.blocked_by.participant == "blocker" and outcome.blocked_by.kind == "vehicle"
    assert outcome.blocked_by.stood_s >= 12.0 - 5.0 and outcome.blocked_by.ahead_m > 0.0
    assert "blocked by the world" in outcome.detail


def test_a_driver_waiting_without_a_barrier_is_not_blocked(world: World) -> None:
    obs = world.reset(2)
    outcome = None
    while outcome is None:  # the ego stands still at its start: nobody bars its way
        obs, outcome = world.step(np.array([0.0, -3.0]))
    assert outcome.kind == "timeout" and outcome.blocked_by is None


def test_barrier_geometry(world: World) -> None:
    first = world.candidates[0]
    mid = first.points[len(first.points) // 10]  # early on the paths: in the entrance lane
    assert bars_every_path(float(mid[0]), float(mid[1]), 1.8, world.candidates)
    far = mid + np.array([30.0, 0.0])
    assert not bars_every_path(float(far[0]), float(far[1]), 1.8, world.candidates)
    start = first.points[0]
    found = nearest_barrier((float(start[0]), float(start[1])),
                            [(0, float(far[0]), float(far[1]), 1.8), (1, float(mid[0]), float(mid[1]), 1.8)],
                            world.candidates)
    assert found is not None and found[0] == 1 and found[1] > 0.0
    assert held_whole_episode(56.0, 60.0) and not held_whole_episode(40.0, 60.0)
