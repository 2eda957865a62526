"""Low-level reader of SUMO ``.net.xml`` files into plain records.

This module only turns XML into typed records (nodes, edges, lanes, connections); it knows nothing
about approaches or stop lines, which :mod:`crossroads.network.junction` derives from them. It reads
every net format from 0.13 up to the current 1.x (SUMO 1.28 still writes net version 1.20): the
elements and attributes used here have kept their meaning, and attributes newer formats added
(``width``, ``outlineShape``, ...) fall back to SUMO's defaults when missing.

Safety: ``defusedxml`` is used when installed. Otherwise the standard library parser is used after
a file-size check: Python's expat (>= 2.4.1) refuses entity-expansion bombs and ``xml.etree`` never
resolves external entities, so an oversized file is the remaining risk.

Frame: SUMO's network coordinates [m], x east, y north (the ``netOffset`` already applied by SUMO).
"""

from __future__ import annotations

import gzip
import io
import math
import xml.etree.ElementTree as ET
from collections.abc import Container
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from crossroads.geometry import FloatArray, drop_repeated_points

try:  # optional hardening; not a dependency of the project
    import defusedxml.ElementTree as _SAFE_ET  # type: ignore[import-untyped]
except ImportError:  # pragma: no cover - depends on the environment
    _SAFE_ET = None

MAX_NET_BYTES = 512 * 1024 * 1024  # [B] refuse larger files: a city-scale net is ~100 MB
DEFAULT_LANE_WIDTH_M = 3.2  # [m] SUMO's default lane width (written only when different)
DEFAULT_CROSSING_WIDTH_M = 4.0  # [m] netconvert's default crossing width
TRAFFIC_LIGHT_TYPES = frozenset(
    {"traffic_light", "traffic_light_unregulated", "traffic_light_right_on_red"}
)

# SUMO's vehicle classes (sumo.dlr.de/docs/Definition_of_Vehicles...#abstract_vehicle_class).
# "disallow" lists are complemented against this set; unknown (deprecated) names that appear in an
# "allow" list of an old net are kept as they are.
SUMO_VEHICLE_CLASSES: frozenset[str] = frozenset(
    {
        "private", "emergency", "authority", "army", "vip", "pedestrian", "passenger", "hov",
        "taxi", "bus", "coach", "delivery", "truck", "trailer", "motorcycle", "moped", "bicycle",
        "evehicle", "tram", "rail_urban", "rail", "rail_electric", "rail_fast", "ship",
        "container", "cable_car", "subway", "aircraft", "wheelchair", "scooter", "drone",
        "custom1", "custom2",
    }
)


class NetXmlError(ValueError):
    """The file is missing, too large, not XML, or not a SUMO network."""


@dataclass(frozen=True)
class NodeRec:
    """A ``<junction>`` element (SUMO calls nodes junctions)."""

    id: str
    type: str
    x: float  # [m]
    y: float  # [m]
    shape: FloatArray | None  # (N, 2) outline [m], or None when absent/degenerate
    inc_lanes: tuple[str, ...]


@dataclass(frozen=True)
class LaneRec:
    """A ``<lane>`` element."""

    id: str
    edge_id: str
    index: int
    width_m: float
    speed_mps: float
    shape: FloatArray  # (N, 2) centre line in the driving direction [m]
    allowed: frozenset[str]
    outline: FloatArray | None = None  # (N, 2) ``outlineShape`` of crossings (net >= 1.20)

    @property
    def length_m(self) -> float:
        if len(self.shape) < 2:
            return 0.0
        return float(np.sum(np.hypot(*np.diff(self.shape, axis=0).T)))


@dataclass(frozen=True)
class EdgeRec:
    """An ``<edge>`` element; ``function`` is "normal", "internal", "crossing" or "walkingarea"."""

    id: str
    function: str
    from_node: str | None
    to_node: str | None
    lane_ids: tuple[str, ...]  # ordered by lane index
    crossing_edges: tuple[str, ...] = ()


@dataclass(frozen=True)
class ConnRec:
    """A ``<connection>`` element (lane-to-lane link)."""

    from_edge: str
    to_edge: str
    from_lane: int
    to_lane: int
    via: str | None  # internal lane id
    tl: str | None  # controlling traffic light id
    link_index: int | None
    dir: str

    @property
    def from_lane_id(self) -> str:
        return f"{self.from_edge}_{self.from_lane}"

    @property
    def to_lane_id(self) -> str:
        return f"{self.to_edge}_{self.to_lane}"


@dataclass
class NetXml:
    """Everything :mod:`crossroads.network.junction` needs from one network file."""

    path: Path
    version: str
    lefthand: bool
    conv_boundary: tuple[float, float, float, float] | None  # (xmin, ymin, xmax, ymax) [m]
    nodes: dict[str, NodeRec] = field(default_factory=dict)
    edges: dict[str, EdgeRec] = field(default_factory=dict)
    lanes: dict[str, LaneRec] = field(default_factory=dict)
    connections: list[ConnRec] = field(default_factory=list)
    tl_logic_ids: set[str] = field(default_factory=set)
    # look-up indexes, filled by :meth:`build_indexes` once everything is read
    _conns_by_from_lane: dict[str, list[ConnRec]] = field(default_factory=dict, repr=False)
    _edges_by_node: dict[str, list[EdgeRec]] = field(default_factory=dict, repr=False)
    # what readers derive from the whole net once and reuse while the parsed net is kept
    derived: dict[str, Any] = field(default_factory=dict, repr=False)

    def build_indexes(self) -> None:
        """Index connections by their from-lane and normal edges by their end nodes."""
        self._conns_by_from_lane.clear()
        self._edges_by_node.clear()
        for c in self.connections:
            self._conns_by_from_lane.setdefault(c.from_lane_id, []).append(c)
        for e in self.edges.values():
            if e.function != "normal":
                continue
            for node in {e.from_node, e.to_node} - {None}:
                self._edges_by_node.setdefault(node, []).append(e)  # type: ignore[arg-type]

    def connections_from_lane(self, lane_id: str) -> list[ConnRec]:
        """Connections leaving a lane (normal or internal)."""
        return self._conns_by_from_lane.get(lane_id, [])

    def edges_at(self, node_id: str) -> list[EdgeRec]:
        """Normal edges starting or ending at a node."""
        return self._edges_by_node.get(node_id, [])


# --- attribute parsing ------------------------------------------------------------------------


def parse_shape(text: str | None) -> FloatArray | None:
    """A SUMO shape ``"x1,y1 x2,y2 ..."`` (z ignored) as an (N, 2) array; None if empty."""
    if not text or not text.strip():
        return None
    try:
        pts = [tuple(float(v) for v in p.split(",")[:2]) for p in text.split()]
    except ValueError as exc:
        raise NetXmlError(f"malformed shape {text[:60]!r}") from exc
    return drop_repeated_points(np.array(pts, dtype=np.float64))


def allowed_classes(allow: str | None, disallow: str | None) -> frozenset[str]:
    """The vehicle classes a lane permits from its ``allow``/``disallow`` attributes.

    SUMO writes at most one of them; neither means every class is allowed.
    """
    if allow is not None:
        names = set(allow.split())
        return SUMO_VEHICLE_CLASSES if "all" in names else frozenset(names)
    if disallow is not None:
        names = set(disallow.split())
        return frozenset() if "all" in names else SUMO_VEHICLE_CLASSES - names
    return SUMO_VEHICLE_CLASSES


def _float(el: ET.Element, name: str, default: float) -> float:
    value = el.get(name)
    return default if value is None or value == "" else float(value)


def _int_or_none(value: str | None) -> int | None:
    return None if value is None or value == "" else int(value)


# --- reading ----------------------------------------------------------------------------------


def open_net(path: str | Path) -> IO[bytes]:
    """A network file opened for reading: ``.gz`` files (``.net.xml.gz``, as SUMO writes them)
    decompressed, at most :data:`MAX_NET_BYTES` either way (a compressed file is read whole, so
    that a small file inflating without end is refused, not parsed)."""
    path = Path(path)
    if not path.is_file():
        raise NetXmlError(f"network file not found: {path}")
    size = path.stat().st_size
    if size > MAX_NET_BYTES:
        raise NetXmlError(f"network file {path} is {size / 2**20:.0f} MiB, above the "
                          f"{MAX_NET_BYTES / 2**20:.0f} MiB limit")
    if path.suffix != ".gz":
        return path.open("rb")
    try:
        with gzip.open(path, "rb") as f:
            data = f.read(MAX_NET_BYTES + 1)
    except (OSError, EOFError) as exc:
        raise NetXmlError(f"{path} is not a readable gzip file: {exc}") from exc
    if len(data) > MAX_NET_BYTES:
        raise NetXmlError(f"network file {path} inflates above the {MAX_NET_BYTES / 2**20:.0f} MiB limit")
    return io.BytesIO(data)


def _parse_tree(path: Path) -> ET.Element:
    parser: Any = _SAFE_ET if _SAFE_ET is not None else ET
    try:
        with open_net(path) as f:
            root = parser.parse(f).getroot()
    except ET.ParseError as exc:
        raise NetXmlError(f"{path} is not well-formed XML: {exc}") from exc
    except Exception as exc:  # defusedxml raises its own errors for forbidden constructs
        raise NetXmlError(f"{path} could not be parsed safely: {exc}") from exc
    if root.tag != "net":
        raise NetXmlError(f"{path} is not a SUMO network: root element is <{root.tag}>, not <net>")
    return root


def _read_lane(el: ET.Element, edge_id: str, default_width_m: float) -> LaneRec:
    lane_id = el.get("id", "")
    shape = parse_shape(el.get("shape"))
    if shape is None:
        raise NetXmlError(f"lane {lane_id!r} has no shape")
    if len(shape) < 2:  # a zero-length internal lane: keep it as a degenerate segment
        shape = np.vstack([shape, shape])
    return LaneRec(
        id=lane_id,
        edge_id=edge_id,
        index=int(el.get("index", "0")),
        width_m=_float(el, "width", default_width_m),
        speed_mps=_float(el, "speed", 13.89),
        shape=shape,
        allowed=allowed_classes(el.get("allow"), el.get("disallow")),
        outline=parse_shape(el.get("outlineShape")),
    )


def _read_edge(el: ET.Element, net: NetXml) -> None:
    edge_id = el.get("id", "")
    function = el.get("function") or "normal"
    # a crossing without a width attribute has netconvert's crossing width, not a lane's
    width = DEFAULT_CROSSING_WIDTH_M if function == "crossing" else DEFAULT_LANE_WIDTH_M
    lanes = sorted((_read_lane(l, edge_id, width) for l in el.iter("lane")), key=lambda l: l.index)
    for lane in lanes:
        net.lanes[lane.id] = lane
    net.edges[edge_id] = EdgeRec(
        id=edge_id,
        function=function,
        from_node=el.get("from"),
        to_node=el.get("to"),
        lane_ids=tuple(l.id for l in lanes),
        crossing_edges=tuple((el.get("crossingEdges") or "").split()),
    )


def _read_node(el: ET.Element) -> NodeRec:
    shape = parse_shape(el.get("shape"))
    if shape is not None and len(shape) < 3:
        shape = None
    return NodeRec(
        id=el.get("id", ""),
        type=el.get("type", ""),
        x=_float(el, "x", math.nan),
        y=_float(el, "y", math.nan),
        shape=shape,
        inc_lanes=tuple((el.get("incLanes") or "").split()),
    )


def _read_connection(el: ET.Element) -> ConnRec:
    return ConnRec(
        from_edge=el.get("from", ""),
        to_edge=el.get("to", ""),
        from_lane=int(el.get("fromLane", "0")),
        to_lane=int(el.get("toLane", "0")),
        via=el.get("via") or None,
        tl=el.get("tl") or None,
        link_index=_int_or_none(el.get("linkIndex")),
        dir=el.get("dir", ""),
    )


def _conv_boundary(root: ET.Element) -> tuple[float, float, float, float] | None:
    loc = root.find("location")
    text = loc.get("convBoundary") if loc is not None else None
    if not text:
        return None
    values = [float(v) for v in text.split(",")]
    return (values[0], values[1], values[2], values[3]) if len(values) == 4 else None


def read_net_xml(path: str | Path) -> NetXml:
    """Parse a SUMO network file into :class:`NetXml` records.

    Raises :class:`NetXmlError` when the file is missing, too large, malformed, or not a network.
    """
    path = Path(path)
    root = _parse_tree(path)
    net = NetXml(
        path=path,
        version=root.get("version", "unknown"),
        lefthand=(root.get("lefthand", "false").lower() == "true"),
        conv_boundary=_conv_boundary(root),
    )
    try:
        for el in root:
            if el.tag == "edge":
                _read_edge(el, net)
            elif el.tag == "junction":
                node = _read_node(el)
                if node.type != "internal":  # internal "junctions" are waiting points, not nodes
                    net.nodes[node.id] = node
            elif el.tag == "connection":
                net.connections.append(_read_connection(el))
            elif el.tag == "tlLogic":
                net.tl_logic_ids.add(el.get("id", ""))
    except (ValueError, TypeError) as exc:
        if isinstance(exc, NetXmlError):
            raise
        raise NetXmlError(f"{path}: malformed attribute: {exc}") from exc
    if not net.edges or not net.nodes:
        raise NetXmlError(f"{path} is a <net> without edges or junctions")
    net.build_indexes()
    return net


def internal_edge_owner(edge_id: str, node_ids: Container[str]) -> str | None:
    """The node an internal/crossing/walking-area edge (``":<node>_<suffix>"``) belongs to.

    Node ids may themselves contain underscores, so the longest prefix that is a node id wins
    (``":a_b_c0"`` belongs to node ``"a_b"`` when it exists, else to ``"a"``). ``node_ids`` must
    hold every node of the net for that rule to hold.
    """
    if not edge_id.startswith(":"):
        return None
    parts = edge_id[1:].split("_")
    for k in range(len(parts) - 1, 0, -1):
        candidate = "_".join(parts[:k])
        if candidate in node_ids:
            return candidate
    return None
