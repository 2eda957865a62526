"""A Junction as 3D drawing data for the viser view: triangle meshes, line segments, signal heads.

Pure geometry (numpy + shapely, no viser): :func:`junction_scene` turns a
:class:`~crossroads.network.road.Junction` into a :class:`SceneData` the viewer hands to viser
as it is. Everything is in SUMO's network frame [m] (x east, y north) with z up; the layers sit
a few centimetres apart so they never z-fight:

* road surface (the drivable area, triangulated by a constrained Delaunay triangulation, holes
  kept) at z = 0; bike lanes just above it;
* sidewalks and walking areas as kerb-high slabs (top faces);
* green belts (medians) raised like a kerbed island;
* crosswalk stripes (zebra bars), lane markings (solid at the edge borders, dashed between the
  lanes of one edge, yellow at the inner border), stop lines as thick white segments;
* one signal head per approach and turn (left, straight, right), on a pole next to the stop line
  at the approach's left kerb, with the tlLogic link indices that colour it.

Sensor sectors (:func:`sector_mesh`) are built in the ego frame, so the viewer can hang them under
the ego and never rebuild them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry import LineString
from shapely.geometry.base import BaseGeometry

from crossroads.geometry import polygons_of, arc_lengths, point_at
from crossroads.network.road import Junction, Lane
from crossroads.perception.sensors import Sensor, sector_polygon

# Heights [m] of the layers (z up).
Z_ROAD = 0.0
Z_BIKE = 0.01
Z_SIDEWALK = 0.12
Z_MEDIAN = 0.18
Z_CROSSWALK = 0.02
Z_MARKING = 0.03
Z_STOP_LINE = 0.035
Z_SENSOR = 0.06
SIGNAL_HEIGHT_M = 4.5  # [m] of the head's centre above the road
SIGNAL_HEAD_SPACING_M = 0.7  # [m] between the heads of one approach
SIGNAL_SETBACK_M = 1.5  # [m] past the stop line, at the approach's left kerb

MARKING_WIDTH_M = 0.15  # [m] lane markings
STOP_LINE_WIDTH_M = 0.4  # [m]
DASH_M = 3.0  # [m] dash length (dash and gap) between lanes of one edge
STRIPE_WIDTH_M = 0.5  # [m] zebra bars, every 1 m along the crossing

TURN_ORDER = ("left", "straight", "right")


@dataclass(frozen=True)
class Mesh:
    """A triangle mesh: vertices (N, 3) float32 [m], faces (M, 3) uint32 (counter-clockwise from above)."""

    vertices: np.ndarray
    faces: np.ndarray

    @property
    def empty(self) -> bool:
        return len(self.faces) == 0

    def area(self) -> float:
        """Total area of the triangles projected on the ground [m²]."""
        if self.empty:
            return 0.0
        a, b, c = (self.vertices[self.faces[:, k], :2].astype(np.float64) for k in range(3))
        cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
        return float(np.sum(np.abs(cross)) / 2.0)

    @staticmethod
    def merge(meshes: Iterable[Mesh]) -> Mesh:
        verts, faces, offset = [], [], 0
        for m in meshes:
            if m.empty:
                continue
            verts.append(m.vertices)
            faces.append(m.faces + offset)
            offset += len(m.vertices)
        if not verts:
            return EMPTY_MESH
        return Mesh(np.concatenate(verts).astype(np.float32), np.concatenate(faces).astype(np.uint32))


EMPTY_MESH = Mesh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32))


@dataclass(frozen=True)
class SignalHead:
    """A signal head: one approach's turn, coloured by the state of its tlLogic links."""

    id: str  # "<approach>/<turn>"
    approach: str
    turn: str
    link_indices: tuple[int, ...]
    position: np.ndarray  # (3,) [m]


@dataclass(frozen=True)
class SceneData:
    """Everything static the 3D view draws for one junction."""

    junction_id: str
    center: np.ndarray  # (2,) [m]
    bounds: tuple[float, float, float, float]  # of the drivable area
    road: Mesh  # the drivable area (junction polygon and car lanes)
    bike_lanes: Mesh
    sidewalks: Mesh  # sidewalks and walking areas
    medians: Mesh  # green belts
    crosswalks: Mesh  # zebra stripes
    stop_lines: np.ndarray  # (K, 2, 3) segments
    solid_lines: np.ndarray  # (K, 2, 3) white, edge borders
    dashed_lines: np.ndarray  # (K, 2, 3) white, between the lanes of one edge
    centre_lines: np.ndarray  # (K, 2, 3) yellow, inner border of each edge
    signal_heads: tuple[SignalHead, ...] = field(default=())


# --- meshes from areas ----------------------------------------------------------------------------




def triangulate(geometry: BaseGeometry | None, z: float = 0.0) -> Mesh:
    """Triangles covering a (multi)polygon exactly, holes included (constrained Delaunay)."""
    if geometry is not None and not geometry.is_valid:
        geometry = shapely.make_valid(geometry)
    polys = [p for p in polygons_of(geometry) if p.area > 1e-9]
    if not polys:
        return EMPTY_MESH
    verts: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    offset = 0
    for poly in polys:
        triangles = shapely.get_parts(shapely.constrained_delaunay_triangles(poly))
        if len(triangles) == 0:
            continue
        # each triangle's ring: 4 coordinates (closed); keep the first three
        coords = np.stack([np.asarray(t.exterior.coords)[:3, :2] for t in triangles])  # (T, 3, 2)
        a, b, c = coords[:, 0], coords[:, 1], coords[:, 2]
        ccw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) > 0
        coords[~ccw] = coords[~ccw][:, ::-1]  # every face counter-clockwise seen from above (+z)
        pts, inverse = np.unique(coords.reshape(-1, 2), axis=0, return_inverse=True)
        verts.append(pts)
        faces.append(inverse.reshape(-1, 3) + offset)
        offset += len(pts)
    if not verts:
        return EMPTY_MESH
    xy = np.concatenate(verts)
    vertices = np.column_stack([xy, np.full(len(xy), z)]).astype(np.float32)
    return Mesh(vertices, np.concatenate(faces).astype(np.uint32))


def _fan(outline: np.ndarray, z: float) -> Mesh:
    """A convex-ish outline (M, 2) as a triangle fan from its first point (for sectors)."""
    n = len(outline)
    faces = np.column_stack([np.zeros(n - 2, int), np.arange(1, n - 1), np.arange(2, n)])
    verts = np.column_stack([outline, np.full(n, z)]).astype(np.float32)
    return Mesh(verts, faces.astype(np.uint32))


def sector_mesh(sensor: Sensor, z: float = Z_SENSOR, n: int = 48) -> Mesh:
    """A sensor's perception sector in the **ego frame** (ego at the origin, heading +x)."""
    outline = sector_polygon(sensor, 0.0, 0.0, 0.0, n=n)
    if sensor.omnidirectional:  # a disc: fan from its centre
        mx, my, _ = sensor.mount_world(0.0, 0.0, 0.0)
        outline = np.vstack([[mx, my], outline, outline[:1]])
    return _fan(outline, z)


# --- lines -----------------------------------------------------------------------------------------


def _segments(polyline: np.ndarray, z: float) -> np.ndarray:
    """A polyline (N, 2) as N-1 segments (N-1, 2, 3)."""
    pts = np.asarray(polyline, dtype=np.float64)
    if len(pts) < 2:
        return np.zeros((0, 2, 3), np.float32)
    p3 = np.column_stack([pts, np.full(len(pts), z)])
    return np.stack([p3[:-1], p3[1:]], axis=1).astype(np.float32)


def _stack(parts: Sequence[np.ndarray]) -> np.ndarray:
    parts = [p for p in parts if len(p)]
    return np.concatenate(parts).astype(np.float32) if parts else np.zeros((0, 2, 3), np.float32)


def _offset(line: np.ndarray, distance_m: float) -> np.ndarray | None:
    """The line moved ``distance_m`` to its left (negative: right); None if it collapses."""
    if len(line) < 2:
        return None
    moved = LineString(line).offset_curve(distance_m)
    if moved.is_empty or moved.geom_type != "LineString":
        return None
    return np.asarray(moved.coords)


def dashes(polyline: np.ndarray, dash_m: float = DASH_M, z: float = Z_MARKING) -> np.ndarray:
    """Dash segments along a polyline: ``dash_m`` painted, ``dash_m`` blank, repeated."""
    pts = np.asarray(polyline, dtype=np.float64)
    if len(pts) < 2:
        return np.zeros((0, 2, 3), np.float32)
    total = float(arc_lengths(pts)[-1])
    out = []
    s = 0.0
    while s < total:
        e = min(s + dash_m, total)
        # a dash follows the line's vertices between its ends (curved lanes stay curved)
        cum = arc_lengths(pts)
        inner = pts[(cum > s) & (cum < e)]
        piece = np.vstack([point_at(pts, s), *inner, point_at(pts, e)]) if len(inner) else \
            np.vstack([point_at(pts, s), point_at(pts, e)])
        out.append(_segments(piece, z))
        s += 2.0 * dash_m
    return _stack(out)


def _markings(lanes: Iterable[Lane]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(solid, dashed, centre) segments for the car lanes, grouped by edge."""
    by_edge: dict[str, list[Lane]] = {}
    for lane in lanes:
        by_edge.setdefault(lane.edge_id, []).append(lane)
    solid, dashed, centre = [], [], []
    for edge_lanes in by_edge.values():
        edge_lanes.sort(key=lambda la: la.index)
        for k, lane in enumerate(edge_lanes):
            right = _offset(np.asarray(lane.centerline, float), -lane.width_m / 2.0)
            if right is not None:
                (solid if k == 0 else dashed).append(
                    _segments(right, Z_MARKING) if k == 0 else dashes(right))
            if k == len(edge_lanes) - 1:
                left = _offset(np.asarray(lane.centerline, float), lane.width_m / 2.0)
                if left is not None:
                    centre.append(_segments(left, Z_MARKING))
    return _stack(solid), _stack(dashed), _stack(centre)


def _zebra(centerline: np.ndarray, width_m: float, z: float = Z_CROSSWALK) -> Mesh:
    """Zebra bars across a crossing: ``STRIPE_WIDTH_M`` wide every metre, along the traffic."""
    line = np.asarray(centerline, dtype=np.float64)
    total = float(arc_lengths(line)[-1]) if len(line) > 1 else 0.0
    bars = []
    half = STRIPE_WIDTH_M / 2.0
    for s in np.arange(0.5, total - half, 1.0):
        a, b = point_at(line, s - half), point_at(line, s + half)
        d = b - a
        norm = math.hypot(*d)
        if norm < 1e-9:
            continue
        n = np.array([-d[1], d[0]]) / norm * (width_m / 2.0 * 0.9)
        quad = np.array([a - n, b - n, b + n, a + n])
        bars.append(Mesh(np.column_stack([quad, np.full(4, z)]).astype(np.float32),
                         np.array([[0, 1, 2], [0, 2, 3]], np.uint32)))
    return Mesh.merge(bars)


# --- signal heads ----------------------------------------------------------------------------------


def _signal_heads(junction: Junction) -> tuple[SignalHead, ...]:
    heads = []
    for approach in junction.approaches:
        h = approach.heading_rad
        forward = np.array([math.cos(h), math.sin(h)])
        left = np.array([-math.sin(h), math.cos(h)])
        stop = np.asarray(approach.stop_line, dtype=np.float64)
        left_end = stop[int(np.argmax(stop @ left))]
        base = left_end + forward * SIGNAL_SETBACK_M
        turns = [t for t in TURN_ORDER if approach.connections_for(t)]  # type: ignore[arg-type]
        for k, turn in enumerate(turns):
            links = tuple(sorted({c.tl_link_index for c in approach.connections_for(turn)  # type: ignore[arg-type]
                                  if c.tl_link_index is not None}))
            if not links:
                continue
            xy = base - left * (SIGNAL_HEAD_SPACING_M * (k + 1))
            heads.append(SignalHead(id=f"{approach.id}/{turn}", approach=approach.id, turn=turn,
                                    link_indices=links,
                                    position=np.array([xy[0], xy[1], SIGNAL_HEIGHT_M], np.float32)))
    return tuple(heads)


# SUMO tlLogic state characters → the head's colour name.
_STATE_COLOUR = {"G": "green", "g": "green", "y": "yellow", "Y": "yellow", "u": "yellow",
                 "r": "red", "R": "red", "s": "red", "o": "off", "O": "off"}


def head_colour(state: str, link_indices: Sequence[int]) -> str:
    """``"green" | "yellow" | "red" | "off"`` for a head from the whole tlLogic state string.

    Several links (one per lane): the most restrictive wins (red over yellow over green)."""
    names = [_STATE_COLOUR.get(state[i], "off") for i in link_indices if 0 <= i < len(state)]
    for name in ("red", "yellow", "green"):
        if name in names:
            return name
    return "off"


# --- the whole junction ----------------------------------------------------------------------------


def junction_scene(junction: Junction) -> SceneData:
    """The static 3D drawing data of a junction."""
    minx, miny, maxx, maxy = junction.drivable_area.bounds
    road = triangulate(junction.drivable_area, Z_ROAD)
    bikes = triangulate(shapely.union_all([lane.polygon() for lane in junction.bike_lanes])
                        if junction.bike_lanes else None, Z_BIKE)
    walk = [lane.polygon() for lane in junction.sidewalks] + list(junction.walking_areas)
    sidewalks = triangulate(shapely.union_all(walk) if walk else None, Z_SIDEWALK)
    medians = Mesh.merge(triangulate(a.median, Z_MEDIAN) for a in junction.approaches)
    crosswalks = Mesh.merge(_zebra(c.centerline, c.width_m) for c in junction.crossings)
    solid, dashed, centre = _markings(junction.lanes.values())
    stops = _stack([_segments(np.asarray(a.stop_line, float), Z_STOP_LINE) for a in junction.approaches])
    return SceneData(
        junction_id=junction.id,
        center=np.asarray(junction.center, dtype=np.float64),
        bounds=(float(minx), float(miny), float(maxx), float(maxy)),
        road=road, bike_lanes=bikes, sidewalks=sidewalks, medians=medians, crosswalks=crosswalks,
        stop_lines=stops, solid_lines=solid, dashed_lines=dashed, centre_lines=centre,
        signal_heads=_signal_heads(junction),
    )
