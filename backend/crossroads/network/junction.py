"""Read any SUMO network's signalized intersection into a :class:`.model.Junction`.

Entry point: :func:`read_junction`. Every junction the reader cannot handle raises
:class:`JunctionError` with a message that says why.

How the parts are derived (SUMO network frame [m], headings [rad] CCW from +x):

- **Which junction**: the given id, or the traffic-light junction nearest the centre of the
  network's ``convBoundary`` (bounding box of the junction positions when absent).
- **Joined nodes**: SUMO sometimes models one signalized intersection as several adjacent nodes
  sharing one traffic light (a divided road meeting a side road, ``tls.join``). Nodes controlled by
  the same traffic light and linked by edges no longer than :data:`MAX_INNER_EDGE_M` form one
  junction; the edges between them become part of the junction area, and movements are traced
  through them. Nodes that ``netconvert --junctions.join`` already merged ("cluster_...") are one
  SUMO junction and need nothing special.
- **Approaches**: the normal edges entering the junction with at least one lane open to passenger
  cars. Entrance lanes are those car lanes by SUMO lane index (0 = the kerb-side lane, the
  rightmost one in right-hand traffic).
- **Leg pairing**: the exit edge of an approach is the outgoing edge that starts nearest the
  approach's end, runs opposite to it (within :data:`OPPOSITE_TOLERANCE_RAD`) and lies on its
  inner side (the left in right-hand traffic); pairs are assigned greedily, nearest first.
- **Median**: when the inner borders of the entrance and exit carriageways are more than
  :data:`MEDIAN_MIN_GAP_M` apart at the stop line, the strip between them over the last
  :data:`MEDIAN_EXTENT_M` metres is the approach's median (green belt).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPoint, Point, Polygon
from shapely.geometry.base import BaseGeometry

from crossroads.geometry import (
    FloatArray,
    drop_repeated_points,
    heading_of,
    point_at,
    polyline_length,
    sub_polyline,
    unit,
    wrap_angle,
)
from crossroads.network.road import (
    SUMO_DIR_TO_TURN,
    Approach,
    Connection,
    Crossing,
    Junction,
    Lane,
    LaneChain,
    Turn,
)
from crossroads.network.netxml import (
    TRAFFIC_LIGHT_TYPES,
    ConnRec,
    EdgeRec,
    LaneRec,
    NetXml,
    NetXmlError,
    internal_edge_owner,
    read_net_xml,
)

MIN_APPROACHES = 3  # an intersection needs at least three legs with car lanes
MAX_INNER_EDGE_M = 25.0  # [m] longest edge between nodes that still form one junction
# (netconvert joins traffic lights up to tls.join-dist = 20 m apart)
MAX_CHAIN_STEPS = 8  # inner edges a single movement may pass before we call the cluster malformed
HEADING_WINDOW_M = 5.0  # [m] the stop-line heading is the chord over the lane's last metres
OPPOSITE_TOLERANCE_RAD = math.radians(60.0)  # exit edge must run within this of the reverse
MAX_LEG_PAIR_DISTANCE_M = 60.0  # [m] exit start to entrance end, farther is another leg
INNER_SIDE_TOLERANCE_M = 1.0  # [m] how far to the outer side an exit start may lie
MEDIAN_MIN_GAP_M = 0.5  # [m] gap between carriageways above which a median is drawn
MEDIAN_EXTENT_M = 80.0  # [m] median drawn this far back from the stop line (~sensor range)
MAX_DEFAULT_CANDIDATES = 50  # traffic-light nodes tried, nearest first, for the default junction
MIN_AREA_M2 = 0.5  # [m²] polygons smaller than this are treated as degenerate
LEAD_IN_MAX_M = 250.0  # [m] how far upstream of a stop line the road towards it is traced
LEAD_OUT_MAX_M = 100.0  # [m] how far downstream of an exit lane's start the road on is traced
LEAD_IN_MAX_BEND_RAD = math.radians(20.0)  # lanes joined into a lead-in or lead-out bend no more than this
CAR_CLASS = "passenger"
FOOT_CLASSES = frozenset({"pedestrian", "wheelchair"})

UNION_GRID_M = 1e-6  # [m] precision grid for polygon unions (see the drivable area)


class JunctionError(ValueError):
    """The network or the requested junction cannot be read as a signalized intersection."""


# --- choosing the junction --------------------------------------------------------------------


def _load(net_file: str | Path) -> NetXml:
    path = Path(net_file)
    try:
        stat = path.stat()
    except OSError:
        stat = None
    try:
        if stat is None:
            return read_net_xml(path)  # raises the reader's own "not found"
        return _load_cached(path.resolve(), stat.st_mtime_ns, stat.st_size)
    except NetXmlError as exc:
        raise JunctionError(str(exc)) from exc


@lru_cache(maxsize=2)
def _load_cached(path: Path, mtime_ns: int, size: int) -> NetXml:
    """The parsed net, kept for the next junction read from the same unchanged file (a city net
    takes seconds to parse; reading its junctions one by one parsed it each time). The reader
    changes nothing of it but its ``derived`` memo."""
    return read_net_xml(path)


def _tl_ids_by_node(net: NetXml) -> dict[str, Counter[str]]:
    """For every node, how many of the connections entering it each traffic light controls
    (kept with the parsed net)."""
    cached = net.derived.get("tl_ids_by_node")
    if cached is not None:
        return cached  # type: ignore[no-any-return]
    result: dict[str, Counter[str]] = {}
    net.derived["tl_ids_by_node"] = result
    for c in net.connections:
        edge = net.edges.get(c.from_edge)
        if c.tl is None or edge is None or edge.function != "normal" or edge.to_node is None:
            continue
        result.setdefault(edge.to_node, Counter())[c.tl] += 1
    return result


def _is_tl_node(net: NetXml, node_id: str) -> bool:
    return net.nodes[node_id].type in TRAFFIC_LIGHT_TYPES


def _net_centre(net: NetXml) -> FloatArray:
    if net.conv_boundary is not None:
        x0, y0, x1, y1 = net.conv_boundary
        return np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0])
    xy = np.array([[n.x, n.y] for n in net.nodes.values()])
    return (xy.min(axis=0) + xy.max(axis=0)) / 2.0


def _some_ids(ids: Iterable[str], limit: int = 8) -> str:
    ids = sorted(ids)
    more = f", ... ({len(ids)} in all)" if len(ids) > limit else ""
    return ", ".join(repr(i) for i in ids[:limit]) + more


def _check_given_node(net: NetXml, junction_id: str) -> str:
    """``junction_id`` if it names a traffic-light node; otherwise a JunctionError saying why."""
    tl_nodes = [n for n in net.nodes if _is_tl_node(net, n)]
    if junction_id not in net.nodes:
        pool = tl_nodes or list(net.nodes)
        kind = "traffic-light junctions" if tl_nodes else "junctions"
        raise JunctionError(
            f"{net.path}: junction {junction_id!r} does not exist; {kind}: {_some_ids(pool)}")
    if not _is_tl_node(net, junction_id):
        hint = f"; traffic-light junctions: {_some_ids(tl_nodes)}" if tl_nodes else ""
        raise JunctionError(
            f"{net.path}: junction {junction_id!r} has no traffic light "
            f"(its type is {net.nodes[junction_id].type!r}){hint}")
    return junction_id


def _default_node(net: NetXml, tl_by_node: dict[str, Counter[str]]) -> str:
    """The traffic-light node nearest the net's centre that forms a readable intersection.

    Nodes that cannot (a pedestrian light on a straight road, a ramp meter) are passed over, so
    a net with one real intersection and a few such lights still reads the intersection; when no
    node qualifies the nearest one is returned and reading it raises the precise error.
    """
    tl_nodes = [n for n in net.nodes if _is_tl_node(net, n)]
    if not tl_nodes:
        raise JunctionError(f"{net.path}: the network has no traffic-light junction")
    centre = _net_centre(net)
    # ties (equidistant nodes) are broken by id so the choice is reproducible
    ordered = sorted(tl_nodes, key=lambda n: (math.hypot(net.nodes[n].x - centre[0],
                                                         net.nodes[n].y - centre[1]), n))
    for node_id in ordered[:MAX_DEFAULT_CANDIDATES]:
        try:
            nodes = _cluster(net, node_id, _tl_id_of(net, node_id, tl_by_node), tl_by_node)
        except JunctionError:
            continue
        incoming, _, _ = _edges_around(net, nodes)
        if sum(1 for e in incoming if _car_lanes(net, e)) >= MIN_APPROACHES:
            return node_id
    return ordered[0]


def _tl_id_of(net: NetXml, node_id: str, tl_by_node: dict[str, Counter[str]]) -> str:
    """The traffic light controlling a node: from its connections' ``tl`` attribute.

    It may differ from the node id (e.g. ``GS_cluster_...``, ``joinedS_...``). Nets whose
    connections carry no ``tl`` fall back to a tlLogic named like the node.
    """
    counts = tl_by_node.get(node_id)
    if counts:
        return counts.most_common(1)[0][0]
    if node_id in net.tl_logic_ids:
        return node_id
    raise JunctionError(
        f"{net.path}: junction {node_id!r} is of type {net.nodes[node_id].type!r} but no "
        f"connection names its traffic light and there is no tlLogic {node_id!r}")


def _edge_length(net: NetXml, edge: EdgeRec) -> float:
    return max((net.lanes[l].length_m for l in edge.lane_ids), default=0.0)


def _cluster(net: NetXml, node_id: str, tl_id: str,
             tl_by_node: dict[str, Counter[str]]) -> tuple[str, ...]:
    """The node and every node reachable over short edges that the same traffic light controls.

    Raises when a short edge leads to a node with a *different* traffic light: the intersection is
    split between two signal programs and no approach/stop-line reading of it would be honest.
    """
    members = {node_id}
    frontier = [node_id]
    while frontier:
        current = frontier.pop()
        for edge in net.edges_at(current):
            other = edge.to_node if edge.from_node == current else edge.from_node
            if other is None or other in members or other not in net.nodes:
                continue
            if _edge_length(net, edge) > MAX_INNER_EDGE_M:
                continue
            other_tls = set(tl_by_node.get(other, ()))
            if tl_id in other_tls:
                members.add(other)
                frontier.append(other)
            elif other_tls and _is_tl_node(net, other):
                raise JunctionError(
                    f"{net.path}: junction {node_id!r} (traffic light {tl_id!r}) is "
                    f"{_edge_length(net, edge):.1f} m (edge {edge.id!r}) from junction {other!r} "
                    f"controlled by another traffic light ({_some_ids(other_tls)}); an "
                    "intersection split between two signal programs is not supported")
    return tuple(sorted(members))


def _edges_around(net: NetXml, nodes: Sequence[str]
                  ) -> tuple[list[EdgeRec], list[EdgeRec], list[EdgeRec]]:
    """The normal edges entering, leaving, and lying inside a set of nodes (sorted by id)."""
    members = set(nodes)
    edges = {e.id: e for n in nodes for e in net.edges_at(n) if e.lane_ids}
    ordered = [edges[k] for k in sorted(edges)]
    incoming = [e for e in ordered if e.to_node in members and e.from_node not in members]
    outgoing = [e for e in ordered if e.from_node in members and e.to_node not in members]
    inner = [e for e in ordered if e.from_node in members and e.to_node in members]
    return incoming, outgoing, inner


# --- lanes and geometry helpers ---------------------------------------------------------------


def _to_lane(rec: LaneRec) -> Lane:
    return Lane(
        id=rec.id,
        edge_id=rec.edge_id,
        index=rec.index,
        width_m=rec.width_m,
        speed_limit_mps=rec.speed_mps,
        centerline=rec.shape,
        allowed_classes=rec.allowed,
    )


def _is_car(rec: LaneRec) -> bool:
    return CAR_CLASS in rec.allowed


def _is_sidewalk(rec: LaneRec) -> bool:
    """Open to people on foot and to no vehicle (wheelchairs count as on foot)."""
    return "pedestrian" in rec.allowed and rec.allowed <= FOOT_CLASSES


def _is_bike_lane(rec: LaneRec) -> bool:
    """Open to bicycles but neither to cars nor to pedestrians."""
    return "bicycle" in rec.allowed and CAR_CLASS not in rec.allowed and \
        "pedestrian" not in rec.allowed


def _lane_polygon(rec: LaneRec) -> Polygon:
    return LineString(rec.shape).buffer(rec.width_m / 2.0, cap_style="flat")


def _heading_near_end(shape: FloatArray, window_m: float = HEADING_WINDOW_M) -> float:
    """Heading [rad] of the chord over the last ``window_m`` metres of a polyline.

    A chord rather than the last segment because SUMO often ends lanes with a tiny kinked segment.
    """
    length = polyline_length(shape)
    start = point_at(shape, length - min(window_m, length))
    if np.allclose(start, shape[-1]):
        return heading_of(shape[-1] - shape[-2])
    return heading_of(shape[-1] - start)


def _heading_near_start(shape: FloatArray, window_m: float = HEADING_WINDOW_M) -> float:
    """Heading [rad] of the chord over the first ``window_m`` metres of a polyline."""
    end = point_at(shape, min(window_m, polyline_length(shape)))
    if np.allclose(end, shape[0]):
        return heading_of(shape[1] - shape[0])
    return heading_of(end - shape[0])


def _mean_heading(headings: Sequence[float]) -> float:
    """Circular mean [rad] of a few headings."""
    return math.atan2(sum(math.sin(h) for h in headings), sum(math.cos(h) for h in headings))


def _offset_polyline(points: FloatArray, distance_m: float) -> FloatArray:
    """The polyline shifted sideways by ``distance_m`` (positive to the left of travel).

    Vertex normals are the average of the adjacent segment normals: exact on straight lanes and
    within centimetres on the gentle bends of lane borders, which is all we draw with it.
    """
    pts = drop_repeated_points(points)
    seg = np.diff(pts, axis=0)
    seg /= np.linalg.norm(seg, axis=1, keepdims=True)
    seg_normals = np.column_stack([-seg[:, 1], seg[:, 0]])
    normals = np.vstack([seg_normals[:1], seg_normals[:-1] + seg_normals[1:], seg_normals[-1:]])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    return pts + distance_m * normals


def _largest_polygon(geom: BaseGeometry) -> Polygon | None:
    """The largest polygon in a (possibly invalid or multi-part) geometry, or None."""
    if not geom.is_valid:
        geom = shapely.make_valid(geom)
    parts = [g for g in getattr(geom, "geoms", [geom]) if isinstance(g, Polygon)]
    for g in getattr(geom, "geoms", []):  # GeometryCollection holding MultiPolygons
        parts.extend(p for p in getattr(g, "geoms", []) if isinstance(p, Polygon))
    parts = [p for p in parts if p.area >= MIN_AREA_M2]
    return max(parts, key=lambda p: p.area) if parts else None


def _outline_polygon(shape: FloatArray | None) -> Polygon | None:
    if shape is None or len(shape) < 3:
        return None
    return _largest_polygon(Polygon(shape))


# --- movements (connections traced to an exit lane) -------------------------------------------


@dataclass(frozen=True)
class _Movement:
    """A connection followed through internal lanes (and inner edges of joined nodes)."""

    to_lane: str
    dirs: tuple[str, ...]  # SUMO ``dir`` of every connection passed
    pieces: tuple[FloatArray, ...]  # lane shapes passed between the entrance and the exit lane
    internal_lanes: tuple[str, ...]  # ids of those lanes (internal lanes and inner-edge lanes)


_DIR_SIGN = {"s": 0, "l": 1, "L": 1, "r": -1, "R": -1, "t": 2}


def _combined_turn(dirs: Sequence[str]) -> Turn | None:
    """Our turn for a movement passing one or several SUMO connections.

    One connection: SUMO's own ``dir``. Several (through joined nodes): left counts +1, right -1,
    turnaround +2; net 0 is straight, ±1 left/right, anything beyond a U-turn.
    """
    if len(dirs) == 1:
        return SUMO_DIR_TO_TURN.get(dirs[0])
    if any(d not in _DIR_SIGN for d in dirs):
        return None
    total = sum(_DIR_SIGN[d] for d in dirs)
    return {0: "straight", 1: "left", -1: "right"}.get(total, "uturn")


def _via_pieces(net: NetXml, conn: ConnRec) -> tuple[list[FloatArray], list[str]]:
    """Shapes and ids of the internal lanes a connection drives through, in order.

    SUMO splits an internal lane where a turning vehicle waits (``:J_3_0`` then ``:J_20_0``); the
    connection leaving each internal lane towards the same destination names the next part.
    """
    shapes: list[FloatArray] = []
    ids: list[str] = []
    lane = conn.via
    while lane is not None and lane in net.lanes and len(ids) < 16:
        shapes.append(net.lanes[lane].shape)
        ids.append(lane)
        nxt = next((c for c in net.connections_from_lane(lane)
                    if c.to_lane_id == conn.to_lane_id), None)
        lane = nxt.via if nxt is not None else None
    return shapes, ids


def _trace(net: NetXml, conn: ConnRec, inner: set[str], outgoing: set[str],
           depth: int = 0) -> list[_Movement]:
    """Every exit lane a connection leads to, passing inner edges of joined nodes."""
    shapes, ids = _via_pieces(net, conn)
    if conn.to_edge in outgoing:
        return [_Movement(conn.to_lane_id, (conn.dir,), tuple(shapes), tuple(ids))]
    if conn.to_edge not in inner or conn.to_lane_id not in net.lanes:
        return []  # leads out of the junction some other way (none in well-formed nets)
    if depth >= MAX_CHAIN_STEPS:
        raise JunctionError(
            f"{net.path}: the movement through {conn.to_edge!r} passes more than "
            f"{MAX_CHAIN_STEPS} edges inside the junction; is the joined junction malformed?")
    inner_shape = net.lanes[conn.to_lane_id].shape
    movements = []
    for nxt in net.connections_from_lane(conn.to_lane_id):
        for m in _trace(net, nxt, inner, outgoing, depth + 1):
            movements.append(_Movement(
                m.to_lane,
                (conn.dir, *m.dirs),
                (*shapes, inner_shape, *m.pieces),
                (*ids, conn.to_lane_id, *m.internal_lanes),
            ))
    return movements


def _concat(pieces: Sequence[FloatArray]) -> FloatArray | None:
    if not pieces:
        return None
    pts = drop_repeated_points(np.vstack(pieces), tol_m=1e-3)
    return pts if len(pts) >= 2 else np.vstack([pts, pts])


def _car_connections(net: NetXml, entrance: Sequence[LaneRec], inner: set[str],
                     outgoing: set[str]) -> tuple[tuple[Connection, ...], set[str]]:
    """The car connections leaving the entrance lanes, and the internal lanes they use."""
    connections: list[Connection] = []
    seen: set[tuple[str, str]] = set()
    used_internal: set[str] = set()
    for lane in entrance:
        for conn in net.connections_from_lane(lane.id):
            for m in _trace(net, conn, inner, outgoing):
                target = net.lanes.get(m.to_lane)
                turn = _combined_turn(m.dirs)
                if target is None or not _is_car(target) or turn is None:
                    continue
                if (lane.id, m.to_lane) in seen:
                    continue
                seen.add((lane.id, m.to_lane))
                used_internal.update(m.internal_lanes)
                inner_edges = tuple(dict.fromkeys(net.lanes[l].edge_id for l in m.internal_lanes
                                                  if not l.startswith(":") and l in net.lanes))
                connections.append(Connection(
                    from_lane=lane.id,
                    to_lane=m.to_lane,
                    turn=turn,
                    via_lane=conn.via,
                    via_shape=_concat(m.pieces),
                    tl_link_index=conn.link_index,
                    inner_edges=inner_edges,
                ))
    return tuple(connections), used_internal


# --- legs: pairing, stop line, median ---------------------------------------------------------


def _lanes_of(net: NetXml, edge: EdgeRec) -> list[LaneRec]:
    return [net.lanes[l] for l in edge.lane_ids]


def _car_lanes(net: NetXml, edge: EdgeRec) -> list[LaneRec]:
    return [l for l in _lanes_of(net, edge) if _is_car(l)]


def _pair_candidates(net: NetXml, incoming: Sequence[EdgeRec], outgoing: Sequence[EdgeRec],
                     inner_sign: float | None) -> list[tuple[float, str, str]]:
    """(distance [m], incoming id, outgoing id) of every plausible leg pair.

    Plausible: the exit runs opposite to the entrance and starts near its end; with
    ``inner_sign`` given, it must also lie on the entrance's inner side.
    """
    candidates: list[tuple[float, str, str]] = []
    for inc in incoming:
        in_lanes = _car_lanes(net, inc)
        end = np.mean([l.shape[-1] for l in in_lanes], axis=0)
        h_in = _mean_heading([_heading_near_end(l.shape) for l in in_lanes])
        for out in outgoing:
            out_lanes = _car_lanes(net, out)
            if not out_lanes:
                continue
            start = np.mean([l.shape[0] for l in out_lanes], axis=0)
            h_out = _mean_heading([_heading_near_start(l.shape) for l in out_lanes])
            offset = start - end
            distance = float(np.hypot(*offset))
            if abs(wrap_angle(h_out - h_in - math.pi)) > OPPOSITE_TOLERANCE_RAD:
                continue
            if distance > MAX_LEG_PAIR_DISTANCE_M:
                continue
            if inner_sign is not None:
                inner_normal = inner_sign * unit(h_in + math.pi / 2.0)
                if float(offset @ inner_normal) < -INNER_SIDE_TOLERANCE_M:
                    continue
            candidates.append((distance, inc.id, out.id))
    return candidates


def _pair_exits(net: NetXml, incoming: Sequence[EdgeRec], outgoing: Sequence[EdgeRec],
                inner_sign: float) -> dict[str, str]:
    """Map each incoming edge id to the outgoing edge of the same leg (see the module doc).

    Greedy, nearest pair first. A first pass insists on the exit lying on the inner side: without
    it a skewed leg's entrance can be nearer to the *next* leg's exit than to its own (cologne1's
    west entrance is 13 m from the south exit). A second pass pairs what is left without it, for
    nets whose drawn geometry contradicts their driving side.
    """
    pairs: dict[str, str] = {}
    taken: set[str] = set()
    for side in (inner_sign, None):
        for _, inc_id, out_id in sorted(_pair_candidates(net, incoming, outgoing, side)):
            if inc_id not in pairs and out_id not in taken:
                pairs[inc_id] = out_id
                taken.add(out_id)
    return pairs


def _stop_line(lanes: Sequence[LaneRec], heading: float) -> FloatArray:
    """(2, 2) segment across the lanes' ends, perpendicular to ``heading``, right end first.

    It spans the outer borders of the outermost lanes. Where SUMO ends the lanes of an edge at
    staggered positions (a bent or skewed edge, the cut following the junction outline) it sits
    at the most upstream lane end: a vehicle stopping at the line then never stands inside the
    junction, whichever lane it is in.
    """
    along_dir, left_dir = unit(heading), unit(heading + math.pi / 2.0)
    ends = np.array([l.shape[-1] for l in lanes])
    widths = np.array([l.width_m for l in lanes])
    origin = ends.mean(axis=0)
    lateral = (ends - origin) @ left_dir
    base = origin + float(np.min((ends - origin) @ along_dir)) * along_dir
    right = float(np.min(lateral - widths / 2.0))
    left = float(np.max(lateral + widths / 2.0))
    return np.array([base + right * left_dir, base + left * left_dir])


def _inner_border(lane: LaneRec, inner_sign: float) -> FloatArray:
    return _offset_polyline(lane.shape, inner_sign * lane.width_m / 2.0)


def _median(net: NetXml, inc: EdgeRec, out: EdgeRec, inner_sign: float) -> Polygon | None:
    """The strip between the entrance and exit carriageways of a leg, if wider than a line.

    The inner lanes are the edges' highest-index lanes of any class (a tram or bus lane in the
    middle is road surface, not median).
    """
    in_lane = _lanes_of(net, inc)[-1]
    out_lane = _lanes_of(net, out)[-1]
    in_border = _inner_border(in_lane, inner_sign)
    out_border = _inner_border(out_lane, inner_sign)
    gap = LineString(out_border).distance(Point(in_border[-1]))
    if gap <= MEDIAN_MIN_GAP_M:
        return None
    inner_normal = inner_sign * unit(_heading_near_end(in_lane.shape) + math.pi / 2.0)
    if float((out_border[0] - in_border[-1]) @ inner_normal) <= 0.0:
        return None  # the exit is drawn on the outer side: no strip between them to speak of
    extent = min(MEDIAN_EXTENT_M, polyline_length(in_border), polyline_length(out_border))
    in_part = sub_polyline(in_border, polyline_length(in_border) - extent, math.inf)
    out_part = sub_polyline(out_border, 0.0, extent)
    # entrance border towards the junction, then exit border away from it: one closed ring
    median = _largest_polygon(Polygon(np.vstack([in_part, out_part])))
    if median is None:
        return None
    # never let the median reach onto a lane (a skewed leg can make the ring overlap them)
    lanes = shapely.union_all([_lane_polygon(l) for l in (*_lanes_of(net, inc), *_lanes_of(net, out))],
                        grid_size=UNION_GRID_M)
    return _largest_polygon(median.difference(lanes))


def _leg_angle(net: NetXml, edge: EdgeRec, centre: FloatArray) -> float:
    """Direction [rad, in [0, 2π)] from the junction centre to where the edge enters it."""
    end = np.mean([l.shape[-1] for l in _lanes_of(net, edge)], axis=0)
    return heading_of(end - centre) % (2.0 * math.pi)


# --- the junction area ------------------------------------------------------------------------


def _junction_polygon(net: NetXml, nodes: Sequence[str], inner_edges: Iterable[EdgeRec],
                      leg_points: Sequence[FloatArray]) -> Polygon:
    """SUMO's junction shape (the union over joined nodes and the edges between them).

    Falls back to the convex hull of the lane ends at the junction when SUMO wrote no usable
    shape, and to the convex hull of a union that is not in one piece.
    """
    parts: list[BaseGeometry] = []
    for n in nodes:
        poly = _outline_polygon(net.nodes[n].shape)
        if poly is not None:
            parts.append(poly)
    if parts:
        for edge in inner_edges:
            parts.extend(_lane_polygon(l) for l in _lanes_of(net, edge))
        union = shapely.union_all(parts, grid_size=UNION_GRID_M)
        if isinstance(union, Polygon):
            return union
        return union.convex_hull  # type: ignore[return-value]
    hull = MultiPoint([tuple(p) for p in leg_points]).convex_hull
    if not isinstance(hull, Polygon):
        raise JunctionError(f"{net.path}: junction {nodes[0]!r} has no shape and its lane ends "
                            "do not span an area")
    return hull


def _crossings(net: NetXml, nodes: Sequence[str], tl_id: str) -> tuple[Crossing, ...]:
    link_by_crossing = {c.to_edge: c.link_index for c in net.connections
                        if c.tl == tl_id and c.link_index is not None}
    crossings = []
    prefixes = tuple(f":{n}_" for n in nodes)  # a quick filter before the exact owner test
    for edge in net.edges.values():
        if edge.function != "crossing" or not edge.id.startswith(prefixes) \
                or internal_edge_owner(edge.id, net.nodes) not in nodes:
            continue
        lane = _lanes_of(net, edge)[0]
        polygon = _outline_polygon(lane.outline) or _lane_polygon(lane)
        crossings.append(Crossing(
            id=edge.id,
            crossed_edges=edge.crossing_edges,
            centerline=lane.shape,
            width_m=lane.width_m,
            polygon=polygon,
            tl_link_index=link_by_crossing.get(edge.id),
        ))
    return tuple(sorted(crossings, key=lambda c: c.id))


def _walking_areas(net: NetXml, nodes: Sequence[str]) -> tuple[Polygon, ...]:
    areas = []
    prefixes = tuple(f":{n}_" for n in nodes)  # a quick filter before the exact owner test
    for edge in sorted((e for e in net.edges.values() if e.id.startswith(prefixes)), key=lambda e: e.id):
        if edge.function != "walkingarea" or internal_edge_owner(edge.id, net.nodes) not in nodes:
            continue
        for lane in _lanes_of(net, edge):
            poly = _outline_polygon(lane.shape)
            if poly is not None:
                areas.append(poly)
    return tuple(areas)


# --- lead-ins and lead-outs: the road before each entrance lane and after each exit lane -----------


def _connections_into(net: NetXml) -> dict[str, list[ConnRec]]:
    """Connections between normal edges, by the lane they lead into (kept with the parsed net:
    every junction read from one net uses the same)."""
    into = net.derived.get("connections_into")
    if into is None:
        into = {}
        for c in net.connections:
            if not (c.from_edge.startswith(":") or c.to_edge.startswith(":")):
                into.setdefault(c.to_lane_id, []).append(c)
        net.derived["connections_into"] = into
    return into  # type: ignore[no-any-return]


def _lane_chain(net: NetXml, lane: LaneRec, into: dict[str, list[ConnRec]] | None,
                avoid_nodes: set[str], max_m: float) -> LaneChain:
    """The road on from ``lane`` for up to ``max_m``: upstream (``into`` given: a lead-in, ending
    with the lane) or downstream (``into`` None: a lead-out, starting with it).

    Each step takes a car connection straight on (SUMO's ``s``, bending at most
    :data:`LEAD_IN_MAX_BEND_RAD` between the two lanes; of several, the first lane id, for a
    reproducible choice), through its internal lanes: a road an ego can drive at cruise speed and
    keep to. It stops where there is no such lane, before an edge that starts (upstream) or ends
    (downstream) at a node of the junction itself, and before an edge it has passed already.
    """
    upstream = into is not None
    pieces: list[tuple[FloatArray, LaneRec | None]] = [(lane.shape, lane)]  # driving order
    length = lane.length_m
    seen = {lane.edge_id}
    current = lane
    while length < max_m:
        if upstream:
            assert into is not None
            options = [(c, c.from_lane_id) for c in into.get(current.id, ())]
        else:
            options = [(c, c.to_lane_id) for c in net.connections_from_lane(current.id)
                       if not c.to_edge.startswith(":")]
        fits = []
        for conn, other_id in options:
            other = net.lanes.get(other_id)
            edge = net.edges.get(other.edge_id) if other is not None else None
            if other is None or edge is None or conn.dir != "s" or not _is_car(other) \
                    or other.edge_id in seen or edge.function != "normal":
                continue
            if (edge.from_node if upstream else edge.to_node) in avoid_nodes:
                continue
            bend = (_heading_near_start(current.shape) - _heading_near_end(other.shape) if upstream
                    else _heading_near_start(other.shape) - _heading_near_end(current.shape))
            if abs(wrap_angle(bend)) <= LEAD_IN_MAX_BEND_RAD:
                fits.append((other_id, conn, other))
        if not fits:
            break
        _, conn, nxt = min(fits, key=lambda f: f[0])
        via, _ = _via_pieces(net, conn)
        if upstream:
            pieces[:0] = [(nxt.shape, nxt), *((v, None) for v in via)]
        else:
            pieces += [*((v, None) for v in via), (nxt.shape, nxt)]
        length += nxt.length_m + sum(polyline_length(v) for v in via)
        seen.add(nxt.edge_id)
        current = nxt
    lanes = [rec for _, rec in pieces if rec is not None]
    starts: list[float] = []  # where each normal lane begins along the joined centre line
    joined: list[FloatArray] = []
    for shape, rec in pieces:
        if rec is not None:
            # a gap between two pieces is bridged by a straight segment that counts before the lane
            starts.append(polyline_length(np.vstack([*joined, shape[:1]])) if joined else 0.0)
        joined.append(shape)
    return LaneChain(
        lane_id=lane.id,
        edges=tuple(l.edge_id for l in lanes),
        lane_indices=tuple(l.index for l in lanes),
        lane_starts_m=tuple(starts),
        centerline=drop_repeated_points(np.vstack(joined), tol_m=1e-3),
    )


def _chain_surface(net: NetXml, chain: LaneChain) -> Polygon:
    return LineString(chain.centerline).buffer(net.lanes[chain.lane_id].width_m / 2.0, cap_style="flat")


# --- assembly ---------------------------------------------------------------------------------


def _build_approach(net: NetXml, inc: EdgeRec, out: EdgeRec | None, inner: set[str],
                    outgoing: set[str], inner_sign: float) -> tuple[Approach, set[str]]:
    entrance = _car_lanes(net, inc)
    heading = _mean_heading([_heading_near_end(l.shape) for l in entrance])
    connections, used_internal = _car_connections(net, entrance, inner, outgoing)
    approach = Approach(
        incoming_edge=inc.id,
        outgoing_edge=out.id if out is not None else None,
        heading_rad=heading,
        entrance_lanes=tuple(_to_lane(l) for l in entrance),
        exit_lanes=tuple(_to_lane(l) for l in _car_lanes(net, out)) if out is not None else (),
        connections=connections,
        stop_line=_stop_line(entrance, heading),
        median=_median(net, inc, out, inner_sign) if out is not None else None,
    )
    return approach, used_internal


def read_junction(net_file: str | Path, junction_id: str | None = None) -> Junction:
    """Read the signalized intersection ``junction_id`` (default: the most central one) of a net.

    ``net_file`` is any SUMO ``.net.xml`` (net versions 0.13 to 1.20, written by SUMO up to 1.28).
    Raises :class:`JunctionError` with the reason when the file or the junction cannot be read.
    """
    net = _load(net_file)
    tl_by_node = _tl_ids_by_node(net)
    if junction_id is not None:
        node_id = _check_given_node(net, junction_id)
    else:
        node_id = _default_node(net, tl_by_node)
    tl_id = _tl_id_of(net, node_id, tl_by_node)
    nodes = _cluster(net, node_id, tl_id, tl_by_node)
    incoming, outgoing, inner_edges = _edges_around(net, nodes)
    approach_edges = [e for e in incoming if _car_lanes(net, e)]
    if len(approach_edges) < MIN_APPROACHES:
        raise JunctionError(
            f"{net.path}: junction {node_id!r} has {len(approach_edges)} approach(es) with car "
            f"lanes ({_some_ids(e.id for e in approach_edges) or 'none'}); at least "
            f"{MIN_APPROACHES} are needed for an intersection")

    inner_sign = -1.0 if net.lefthand else 1.0  # the median side: left in right-hand traffic
    centre = np.mean([[net.nodes[n].x, net.nodes[n].y] for n in nodes], axis=0)
    approach_edges.sort(key=lambda e: (_leg_angle(net, e, centre), e.id))
    pairs = _pair_exits(net, approach_edges, outgoing, inner_sign)
    inner_ids, outgoing_ids = {e.id for e in inner_edges}, {e.id for e in outgoing}

    approaches: list[Approach] = []
    used_internal: set[str] = set()
    for inc in approach_edges:
        out = net.edges[pairs[inc.id]] if inc.id in pairs else None
        approach, used = _build_approach(net, inc, out, inner_ids, outgoing_ids, inner_sign)
        approaches.append(approach)
        used_internal |= used

    lanes: dict[str, Lane] = {}
    for a in approaches:
        lanes.update((l.id, l) for l in a.entrance_lanes)
    exit_car_lanes = [l for e in outgoing for l in _car_lanes(net, e)]
    lanes.update((l.id, _to_lane(l)) for l in exit_car_lanes)

    leg_points = [l.shape[-1] for e in incoming for l in _lanes_of(net, e)] + \
                 [l.shape[0] for e in outgoing for l in _lanes_of(net, e)]
    polygon = _junction_polygon(net, nodes, inner_edges, leg_points)
    car_surfaces = [_lane_polygon(net.lanes[i]) for i in sorted(used_internal)
                    if i in net.lanes and _is_car(net.lanes[i])]
    entrance_recs = [net.lanes[l.id] for a in approaches for l in a.entrance_lanes]
    # grid_size: lanes that share a border up to rounding can make GEOS drop a whole polygon
    # from a plain union (seen with GEOS 3.14 on rotated layouts); snapping to 1 µm avoids it.
    drivable = shapely.union_all([polygon, *car_surfaces,
                            *(_lane_polygon(l) for l in (*entrance_recs, *exit_car_lanes))],
                           grid_size=UNION_GRID_M)

    leg_lanes = [l for e in (*incoming, *outgoing) for l in _lanes_of(net, e)]
    into = _connections_into(net)
    lead_ins = {l.id: _lane_chain(net, net.lanes[l.id], into, set(nodes), LEAD_IN_MAX_M)
                for a in approaches for l in a.entrance_lanes}
    lead_outs = {l.id: _lane_chain(net, l, None, set(nodes), LEAD_OUT_MAX_M) for l in exit_car_lanes}
    # the road before the entrance lanes and after the exit lanes is road too: an ego may start on
    # the first, and leaves over the second where an exit edge is a stub
    chains = [c for c in (*lead_ins.values(), *lead_outs.values()) if len(c.edges) > 1]
    if chains:
        drivable = shapely.union_all([drivable, *(_chain_surface(net, c) for c in chains)],
                                     grid_size=UNION_GRID_M)
    return Junction(
        id=node_id,
        tl_id=tl_id,
        net_file=Path(net_file),
        center=centre,
        polygon=polygon,
        approaches=tuple(approaches),
        lanes=lanes,
        drivable_area=drivable,
        crossings=_crossings(net, nodes, tl_id),
        sidewalks=tuple(_to_lane(l) for l in leg_lanes if _is_sidewalk(l)),
        walking_areas=_walking_areas(net, nodes),
        bike_lanes=tuple(_to_lane(l) for l in leg_lanes if _is_bike_lane(l)),
        exit_edges=tuple(sorted(e.id for e in outgoing)),
        node_ids=nodes,
        lead_ins=lead_ins,
        lead_outs=lead_outs,
    )
