"""Where a participant drives next: its lanes through the junction, from a real SUMO net."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crossroads.geometry import arc_lengths
from crossroads.network.junction import read_junction
from crossroads.sim.lanes_ahead import centre_line, drive_along, lane_successors, lanes_ahead, next_edge
from support import SUMO_RL_NET


@pytest.fixture(scope="module")
def junction():
    if not SUMO_RL_NET.exists():
        pytest.skip(f"{SUMO_RL_NET} is not here")
    return read_junction(SUMO_RL_NET)


def test_next_edge_of_a_route() -> None:
    assert next_edge(("a", "b", "c"), "b") == "c"
    assert next_edge(("a", "b"), "b") is None
    assert next_edge(("a", "b"), ":J_0") is None  # internal edges are not on routes


def test_every_connection_leads_through_its_internal_lane_to_its_exit(junction) -> None:
    successors = lane_successors(junction.approaches)
    for approach in junction.approaches:
        for c in approach.connections:
            if not c.via_lane:
                continue
            to_edge = c.to_lane.rsplit("_", 1)[0]
            via, exit_lane = successors[(c.from_lane, to_edge)]  # one way in per exit edge: the first
            assert exit_lane.rsplit("_", 1)[0] == to_edge
            assert successors[(via, "")] == (exit_lane,)
            assert successors[(c.via_lane, "")] == (c.to_lane,)


def test_the_line_ahead_turns_where_the_route_turns(junction) -> None:
    """A car on an entrance lane whose route turns left: its lanes ahead are the entrance lane, the
    connection's internal lane and the exit lane, and driving along them turns it by about +90°."""
    shapes = {lane.id: lane.centerline for lane in junction.lanes.values()}
    for a in junction.approaches:
        for c in a.connections:
            if c.via_lane and c.via_shape is not None:
                shapes[c.via_lane] = c.via_shape
    successors = lane_successors(junction.approaches)
    turning = next(c for a in junction.approaches for c in a.connections if c.turn == "left" and c.via_lane)
    route = (turning.from_lane.rsplit("_", 1)[0], turning.to_lane.rsplit("_", 1)[0])
    lanes = lanes_ahead(successors, turning.from_lane, route)
    assert lanes[0] == turning.from_lane and lanes[-1].rsplit("_", 1)[0] == route[1] and len(lanes) == 3
    assert lanes_ahead(successors, lanes[1], route) == lanes[1:]  # from inside the junction on
    assert lanes_ahead(successors, turning.from_lane, route[:1]) == (turning.from_lane,)  # the route ends here
    line = centre_line(shapes, lanes)
    x, y = shapes[turning.from_lane][-1] + (shapes[turning.from_lane][0] - shapes[turning.from_lane][-1]) * 0.05
    xy, heading = drive_along(line, float(x), float(y), 8.0, 100)  # 80 m from near the line: through the turn
    turned = (heading[-1] - heading[0] + math.pi) % (2 * math.pi) - math.pi
    assert turned == pytest.approx(math.pi / 2, abs=0.3)
    assert centre_line(shapes, ("nowhere_0",)) is None  # off the junction's lanes: the caller uses the curvature


def test_driving_along_a_corner_keeps_the_speed_and_goes_on_straight_past_the_end() -> None:
    corner = centre_line({"a_0": np.array([[0.0, 0.0], [10.0, 0.0]]), "b_0": np.array([[10.0, 10.0]])}, ("a_0", "b_0"))
    xy, heading = drive_along(corner, 0.0, 0.3, 5.0, 60)  # 30 m at 5 m/s from the foot (0, 0)
    assert np.allclose(xy[9], (5.0, 0.0)) and heading[9] == pytest.approx(0.0)
    assert np.allclose(xy[29], (10.0, 5.0)) and heading[29] == pytest.approx(math.pi / 2)
    assert np.allclose(xy[-1], (10.0, 20.0))  # on straight past the end
    travelled = arc_lengths(np.vstack([[0.0, 0.0], xy[:40]]))[-1]
    assert travelled == pytest.approx(20.0, abs=0.5)  # cutting the corner's one step at most
    still, _ = drive_along(corner, 4.0, -1.0, 0.0, 5)
    assert np.allclose(still, (4.0, 0.0))  # standing: on its foot
