"""Policy ``sumo``: SUMO's own driver drives the ego, judged by the world's judge like any policy."""

from __future__ import annotations

import libsumo
import pytest

from crossroads.evaluation.episode import run_episode
from crossroads.evaluation.sumo_driver import SumoDriverPolicy
from crossroads.intersections import catalogue
from crossroads.sim.config import WorldConfig
from crossroads.sim.traffic import NO_TRAFFIC, TrafficDemand
from crossroads.sim.world import EGO_ID, World


@pytest.fixture(scope="module")
def net():
    return catalogue.build("c_three_lane")


def test_sumo_driver_passes_an_empty_junction(net) -> None:
    config = WorldConfig(net_file=net, task="left", demand=NO_TRAFFIC, warmup_s=0.0, timeout_s=60.0)
    with World(config) as world:
        result = run_episode(world, SumoDriverPolicy(), seed=4)
    assert result.outcome == "passed"
    assert result.travel_time_s is not None and 2.0 < result.travel_time_s < 15.0
    assert result.blocked_by is None


def test_sumo_driver_is_seeded(net) -> None:
    config = WorldConfig(net_file=net, task="straight", demand=TrafficDemand(), warmup_s=30.0,
                         timeout_s=40.0)
    with World(config) as world:
        first = run_episode(world, SumoDriverPolicy(), seed=9)
        again = run_episode(world, SumoDriverPolicy(), seed=9)
    assert first == again


def test_a_collision_with_sumos_ego_is_judged_on_the_true_footprints(net) -> None:
    config = WorldConfig(net_file=net, task="left", demand=NO_TRAFFIC, warmup_s=0.0, timeout_s=30.0)
    with World(config) as world:
        world.reset(7, sumo_driver=SumoDriverPolicy().driver)
        exit_edge = world.junction.lanes[world.candidates[0].exit_lane].edge_id
        libsumo.route.add("intruder_route", [world.approach.incoming_edge, exit_edge])
        libsumo.vehicle.add("intruder", "intruder_route", typeID="car", depart="now", departLane="best")
        _, outcome = world.step(None)  # the intruder enters the network
        assert outcome is None
        x, y, heading, _ = world.session.vehicle_pose(EGO_ID)
        world.session.set_speed("intruder", 0.0)
        world.session.move_vehicle("intruder", x + 1.0, y, heading)  # onto the ego's footprint
        _, outcome = world.step(None)
    assert outcome is not None and outcome.kind == "collision"
    assert outcome.detail == "hit vehicle intruder" and outcome.other_kind == "vehicle"


def test_step_refuses_a_mix_of_drivers(net) -> None:
    config = WorldConfig(net_file=net, task="left", demand=NO_TRAFFIC, warmup_s=0.0, timeout_s=5.0)
    with World(config) as world:
        world.reset(1)
        with pytest.raises(ValueError, match="SUMO drives"):
            world.step(None)
