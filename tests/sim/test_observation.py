"""The observation's static map: lane shapes whose route geometry is worked out once."""

from __future__ import annotations

import math
import pickle

import numpy as np

from crossroads.sim.observation import LaneShapes, participant_curvatures
from crossroads.sim.other import route_curvature, route_shape

ARC = np.array([[10.0 * math.cos(a), 10.0 * math.sin(a)] for a in np.linspace(0.0, 1.5, 40)])  # κ = 0.1
LINE = np.array([[0.0, 0.0], [5.0, 0.0], [5.0, 0.0], [20.0, 0.0]])  # a repeated vertex, as SUMO writes some
ROWS = np.array([[10.0 * math.cos(0.7), 10.0 * math.sin(0.7), 5.0], [8.0, 0.1, 5.0], [9.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
LANES = ["arc", "line", "line", "unknown"]
KINDS = ["vehicle", "cyclist", "pedestrian", "vehicle"]


def test_the_worlds_lane_shapes_give_the_curvatures_of_plain_ones_bit_for_bit() -> None:
    plain = {"arc": ARC, "line": LINE}
    cached = LaneShapes(plain)
    expected = participant_curvatures(plain, LANES, ROWS, KINDS)
    for _ in range(2):  # the second time from the cached geometry
        np.testing.assert_array_equal(participant_curvatures(cached, LANES, ROWS, KINDS), expected)
    assert expected[0] == route_curvature(ARC, *ROWS[0][:2]) and abs(expected[0] - 0.1) < 0.002
    assert expected[2] == 0.0 and expected[3] == 0.0  # a pedestrian; a lane the map does not describe


def test_a_lanes_geometry_is_worked_out_once_and_again_for_a_new_shape() -> None:
    shapes = LaneShapes({"line": LINE})
    first = shapes.route("line")
    assert first is shapes.route("line") and shapes.route("elsewhere") is None
    np.testing.assert_array_equal(first.points, route_shape(LINE).points)  # the repeated vertex dropped
    assert len(first.points) == 3 and first.cum[-1] == 20.0
    shapes["line"] = ARC
    np.testing.assert_array_equal(shapes.route("line").cum, route_shape(ARC).cum)


def test_lane_shapes_survive_pickling_with_what_they_cached() -> None:
    shapes = LaneShapes({"arc": ARC})
    shapes.route("arc")
    copy = pickle.loads(pickle.dumps(shapes))
    assert isinstance(copy, LaneShapes) and copy.keys() == shapes.keys()
    np.testing.assert_array_equal(copy.route("arc").cum, shapes.route("arc").cum)
