"""Crossings end on the kerb: every place a pedestrian waits lies on the walking area, so nobody
waiting for the walk stands on the carriageway where turning cars sweep."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, Point, Polygon, box

from crossroads.intersections import catalogue
from crossroads.intersections.crossing_ends import BODY_HALF_WIDTH_M, extended_centre_line

SIX = ("a_single_lane", "b_two_lane", "c_three_lane", "d_irregular_skewed", "e_irregular_oblique",
       "f_irregular_wide")


def _shape(text: str) -> np.ndarray:
    return np.array([[float(v) for v in p.split(",")[:2]] for p in text.split()])


def test_a_square_end_on_a_rounded_kerb_moves_until_all_waiting_places_are_on_it() -> None:
    # a kerb bending away: the walking area is everything right of x = 7 + (y + 11)^2 / 8
    kerb = [(7.0 + (y + 11.0) ** 2 / 8.0, y) for y in np.linspace(-15.0, -7.0, 30)]
    ground = Polygon([*kerb, (20.0, -7.0), (20.0, -15.0)])
    line = extended_centre_line(np.array([[-7.0, -13.0], [7.0, -13.0]]), 4.0, ground)
    end_x = line[-1][0]
    # the waiting stripe nearest the junction (y = -11 + 0.25) needs x >= 7 + (0.25)^2/8 ... and the
    # farthest (y = -14.75) x >= 7 + 3.75^2 / 8 = 8.76; plus half a body
    assert end_x == pytest.approx(7.0 + 3.75 ** 2 / 8.0 + BODY_HALF_WIDTH_M, abs=0.06)
    assert line[0] == (-7.0 - BODY_HALF_WIDTH_M, -13.0)  # no ground on that side: the body margin only


def test_an_end_on_a_straight_kerb_moves_by_the_body_margin() -> None:
    ground = box(7.0, -20.0, 12.0, 0.0)
    line = extended_centre_line(np.array([[-7.0, -13.0], [7.0, -13.0]]), 4.0, ground)
    assert line[-1] == pytest.approx((7.0 + BODY_HALF_WIDTH_M, -13.0))


@pytest.mark.parametrize("name", SIX)
def test_nobody_waiting_at_a_crossing_of_the_catalogue_stands_on_a_car_lane(name: str) -> None:
    root = ET.parse(catalogue.build(name)).getroot()
    car_lanes, crossings = [], []
    for edge in root.iter("edge"):
        for lane in edge.iter("lane"):
            points = _shape(lane.get("shape", ""))
            width = float(lane.get("width", "3.2"))
            if edge.get("function") == "crossing":
                crossings.append((points, width))
            elif "passenger" in lane.get("allow", "passenger") and len(points) >= 2:
                car_lanes.append(LineString(points).buffer(width / 2.0, cap_style="flat"))
    road = shapely.union_all(car_lanes)
    assert crossings
    for points, width in crossings:
        for end, inner in ((points[0], points[1]), (points[-1], points[-2])):
            out = (end - inner) / np.linalg.norm(end - inner)
            across = np.array([-out[1], out[0]])
            for offset in np.linspace(-(width / 2 - BODY_HALF_WIDTH_M), width / 2 - BODY_HALF_WIDTH_M, 5):
                body = Point(*(end + offset * across)).buffer(BODY_HALF_WIDTH_M)
                assert road.intersection(body).area < 1e-3, (name, end, offset)
