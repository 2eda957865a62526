"""Crossings that end on the kerb: where pedestrians wait for their walk.

netconvert lays a crossing across its leg at the junction's border, with ends square to the
crossing; the kerb there is already bending round the corner. SUMO's pedestrians wait for their
walk at the crossing's end, spread over its width, so on a rounded corner the stripes on the
junction's side wait out on the carriageway: on ``b_two_lane`` (kerb radius 6 m, 4 m crossings)
up to 1.1 m beyond the kerb, where a right-turning car sweeps — the collisions of SUMO's own driver
with "waiting" pedestrians on the nominal right turns.

So every crossing end is moved out along the crossing until each place a pedestrian may wait
(its width, less half a body either side) lies on the walking area at that end and a whole body
there keeps off every car lane (the approach lanes and the shapes the build gives the internal
ones), and then by half a body more, so nobody waiting stands on the road. Ends that already lie on a straight kerb
move by the body margin alone. Pure geometry on the pass-1 net (``intersections/build.py`` gives the
result to netconvert as the crossings' ``shape``).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon

# [m] half a pedestrian's body: SUMO's default pedestrian is 0.5 m wide (its vType width)
BODY_HALF_WIDTH_M = 0.25
# [m] the farthest a crossing end is moved; a corner needing more keeps netconvert's shape
MAX_EXTENSION_M = 4.0
EXTENSION_STEP_M = 0.05
_WAITING_POINTS = 7  # places across the crossing's width checked for standing on the walking area

Shape = list[tuple[float, float]]


def kerbside_crossing_shapes(net_file: str | Path,
                             car_paths: Iterable[tuple[np.ndarray, float]] = ()) -> dict[frozenset[str], Shape]:
    """For each crossing of ``net_file`` (keyed by the set of edges it crosses), its centre line
    with both ends moved onto the walking areas and off the car lanes: the net's normal car lanes
    and ``car_paths`` (centre line, width), the internal lanes' shapes to be (see the module
    docstring)."""
    root = ET.parse(net_file).getroot()
    walking_areas: list[Polygon] = []
    car_areas = [LineString(points).buffer(width / 2.0, cap_style="flat") for points, width in car_paths
                 if len(points) >= 2]
    crossings: list[tuple[frozenset[str], np.ndarray, float]] = []
    for edge in root.iter("edge"):
        function = edge.get("function")
        lane = edge.find("lane")
        if lane is None:
            continue
        points = _points(lane)
        if function is None and len(points) >= 2:  # a normal edge: its car lanes
            car_areas.extend(LineString(_points(car)).buffer(float(car.get("width", "3.2")) / 2.0, cap_style="flat")
                             for car in edge.iter("lane") if "passenger" in car.get("allow", "passenger"))
            continue
        if function == "walkingarea" and len(points) >= 3:
            polygon = Polygon(points)
            walking_areas.append(polygon if polygon.is_valid else polygon.buffer(0))
        elif function == "crossing" and len(points) >= 2:
            edges = frozenset(edge.get("crossingEdges", "").split())
            crossings.append((edges, points, float(lane.get("width", "4"))))
    if not walking_areas:
        return {}
    ground = shapely.union_all(walking_areas)
    road = shapely.union_all(car_areas) if car_areas else None
    return {edges: extended_centre_line(points, width, ground, road) for edges, points, width in crossings}


def extended_centre_line(points: np.ndarray, width_m: float, ground: shapely.Geometry,
                         road: shapely.Geometry | None = None) -> Shape:
    """``points`` (a crossing's centre line) with each end moved outward until every waiting place
    across ``width_m`` stands on ``ground`` with a whole body off ``road``, plus
    :data:`BODY_HALF_WIDTH_M`."""
    start, end = points[0], points[-1]
    out_at_start = _unit(start - points[1])
    out_at_end = _unit(end - points[-2])
    new_start = start + _extension(start, out_at_start, width_m, ground, road) * out_at_start
    new_end = end + _extension(end, out_at_end, width_m, ground, road) * out_at_end
    middle = [tuple(map(float, p)) for p in points[1:-1]]
    return [tuple(map(float, new_start)), *middle, tuple(map(float, new_end))]


def _extension(end: np.ndarray, outward: np.ndarray, width_m: float, ground: shapely.Geometry,
               road: shapely.Geometry | None) -> float:
    """How far to move one end: the first step at which all its waiting places are on ``ground``,
    plus the body margin; only the body margin when none is found within :data:`MAX_EXTENSION_M`."""
    across = np.array([-outward[1], outward[0]])
    half = max(width_m / 2.0 - BODY_HALF_WIDTH_M, 0.0)
    offsets = np.linspace(-half, half, _WAITING_POINTS)
    for step in np.arange(0.0, MAX_EXTENSION_M + 1e-9, EXTENSION_STEP_M):
        centre = end + step * outward
        places = [Point(*(centre + o * across)) for o in offsets]
        if all(ground.covers(p) for p in places) and (
                road is None or not any(road.intersects(p.buffer(2 * BODY_HALF_WIDTH_M)) for p in places)):
            return float(step) + BODY_HALF_WIDTH_M
    return BODY_HALF_WIDTH_M


def _points(lane: ET.Element) -> np.ndarray:
    return np.array([[float(v) for v in p.split(",")[:2]] for p in lane.get("shape", "").split()])


def _unit(vector: np.ndarray) -> np.ndarray:
    norm = math.hypot(float(vector[0]), float(vector[1]))
    return vector / norm if norm > 0 else np.array([1.0, 0.0])
