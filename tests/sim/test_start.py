"""Where the ego enters (sim/start.py): along its route, on the edges before a short entrance lane."""

from __future__ import annotations

import pytest

from crossroads.constants import EGO_LENGTH_M
from crossroads.network.junction import read_junction
from crossroads.sim.config import EgoStart, WorldConfig
from crossroads.sim.start import StartError, longest_start_m, place_ego, start_problem
from crossroads.sim.traffic import NO_TRAFFIC
from crossroads.sim.world import World
from support import COLOGNE1_NET

# cologne1's approach from the south-west: its lanes are 41 m long, the edge before them 48 m
APPROACH = "27115123#3"
LANE = "27115123#3_1"


@pytest.fixture(scope="module")
def cologne():
    return read_junction(COLOGNE1_NET)


def test_a_start_beyond_a_short_lane_is_on_the_edge_before(cologne) -> None:
    lane = cologne.lanes[LANE]
    assert lane.length_m < 40.0 + EGO_LENGTH_M  # the default start does not fit on the lane itself
    lead = cologne.lead_in(LANE)
    assert lead.edges == ("27115123#2", APPROACH) and lead.length_m > 85.0
    p = place_ego(cologne, LANE, 40.0, ("32038056#0",))
    assert p.route_edges == ("27115123#2", APPROACH, "32038056#0")  # SUMO routes it from there
    assert p.depart_lane == lead.lane_indices[0]
    # the ego's front bumper 40 m before the stop line along the road
    behind = lead.length_m - 40.0 - EGO_LENGTH_M / 2.0
    assert behind < lead.lane_starts_m[1]
    near = place_ego(cologne, LANE, 10.0, ("32038056#0",))
    assert near.route_edges == (APPROACH, "32038056#0") and near.depart_lane == lane.index


def test_only_a_road_too_short_is_refused_naming_the_longest_start(cologne) -> None:
    room = longest_start_m(cologne, LANE)
    assert room == pytest.approx(cologne.lead_in(LANE).length_m - EGO_LENGTH_M)
    assert start_problem(cologne, LANE, room) is None
    problem = start_problem(cologne, LANE, 500.0)
    assert problem == (f"500 m does not fit before the stop line of lane '{LANE}': the road leading to it "
                       f"(27115123#2 -> {APPROACH}) is {cologne.lead_in(LANE).length_m:.1f} m long, so the ego "
                       f"can start at most {room:.1f} m before the line")
    with pytest.raises(StartError, match="at most"):
        place_ego(cologne, LANE, 500.0, ())


def test_the_world_starts_the_ego_there() -> None:
    cfg = WorldConfig(net_file=COLOGNE1_NET, task="left", approach=APPROACH, demand=NO_TRAFFIC,
                      warmup_s=1.0, timeout_s=5.0, ego_start=EgoStart(distance_to_stop_line_m=60.0))
    with World(cfg) as world:
        obs = world.reset(1)
        assert world.session.vehicle_lane("ego").startswith("27115123#2_")
        assert obs.distance_to_stop_line_m == pytest.approx(60.0, abs=1.0)
        for _ in range(20):
            obs, outcome = world.step([0.0, 0.0])
            assert outcome is None
    with pytest.raises(StartError, match="at most"):
        World(WorldConfig(net_file=COLOGNE1_NET, task="left", approach=APPROACH,
                          ego_start=EgoStart(distance_to_stop_line_m=500.0)))
