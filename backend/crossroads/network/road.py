"""The Junction: what the rest of Crossroads knows about a signalized intersection.

Read from any SUMO ``.net.xml`` by :mod:`crossroads.network.junction`; used by the planner, the
world, the plots and the API. Frozen dataclasses of plain values (numpy arrays for shapes,
shapely geometry for areas), so they are cheap to pass around and never change once read.

Frame: SUMO's network coordinates [m], x east, y north. Headings [rad] CCW from +x.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from shapely.geometry import LineString, Polygon
from shapely.geometry.base import BaseGeometry

from crossroads.geometry import FloatArray, end_heading, polyline_length, start_heading

Turn = Literal["left", "straight", "right", "uturn"]
TASKS: tuple[Turn, ...] = ("left", "straight", "right")

# SUMO's connection "dir" codes → our turn names (partially-left/right count as left/right).
SUMO_DIR_TO_TURN: dict[str, Turn] = {
    "s": "straight", "l": "left", "L": "left", "r": "right", "R": "right", "t": "uturn",
}


@dataclass(frozen=True, eq=False)
class Lane:
    """One SUMO lane, its centre line in the driving direction."""

    id: str
    edge_id: str
    index: int  # SUMO lane index: 0 is the rightmost lane of its edge
    width_m: float
    speed_limit_mps: float
    centerline: FloatArray  # (N, 2) [m], in the driving direction
    allowed_classes: frozenset[str]  # SUMO vehicle classes allowed on the lane

    @property
    def length_m(self) -> float:
        return polyline_length(self.centerline)

    @property
    def start(self) -> FloatArray:
        return self.centerline[0]

    @property
    def end(self) -> FloatArray:
        return self.centerline[-1]

    @property
    def start_heading(self) -> float:
        return start_heading(self.centerline)

    @property
    def end_heading(self) -> float:
        return end_heading(self.centerline)

    @property
    def allows_cars(self) -> bool:
        return "passenger" in self.allowed_classes

    def polygon(self) -> Polygon:
        """The lane's surface: its centre line widened by half its width each side."""
        return LineString(self.centerline).buffer(self.width_m / 2.0, cap_style="flat")


@dataclass(frozen=True)
class Connection:
    """A movement through the junction from an entrance lane to an exit lane."""

    from_lane: str
    to_lane: str
    turn: Turn
    via_lane: str | None  # SUMO's internal lane through the junction, if any
    via_shape: FloatArray | None  # its centre line (SUMO's own path), for drawing and comparison
    tl_link_index: int | None  # index into the traffic light's state string
    # the normal edges between the two nodes of a joined junction the movement passes (SUMO routes
    # over them: from_lane's edge, these, to_lane's edge); empty at a one-node junction
    inner_edges: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class Approach:
    """One leg of the junction as seen by a vehicle driving in: its incoming edge and exit edge."""

    incoming_edge: str
    outgoing_edge: str | None  # the exit edge of the same leg, if the leg has one
    heading_rad: float  # direction of travel into the junction at the stop line
    entrance_lanes: tuple[Lane, ...]  # car lanes of the incoming edge, rightmost first
    exit_lanes: tuple[Lane, ...]  # car lanes of the outgoing edge of this leg, rightmost first
    connections: tuple[Connection, ...]  # every car connection leaving the entrance lanes
    stop_line: FloatArray  # (2, 2): the segment across the entrance lanes at their ends
    median: Polygon | None = None  # the green belt between the entrance and exit lanes, if any

    @property
    def id(self) -> str:
        return self.incoming_edge

    def turns_of(self, lane_id: str) -> frozenset[Turn]:
        """The turns an entrance lane allows (from its connections)."""
        return frozenset(c.turn for c in self.connections if c.from_lane == lane_id)

    def connections_for(self, turn: Turn) -> tuple[Connection, ...]:
        return tuple(c for c in self.connections if c.turn == turn)


@dataclass(frozen=True, eq=False)
class LaneChain:
    """Consecutive lanes along one road: the road before an entrance lane's stop line (its
    lead-in) or after an exit lane's start (its lead-out).

    Real nets often end an edge a few metres from the junction (a node where a lane is added, a
    previous junction, a 0.2 m stub an OSM import left): a vehicle starting 40 m out starts on the
    edges before the entrance lane, and one leaving drives on over the edges after the exit lane.
    ``edges`` and ``lane_indices`` say which normal lane each stretch is (what SUMO routes on), in
    the driving direction; ``centerline`` runs through the internal lanes between them.
    """

    lane_id: str  # the entrance lane (a lead-in ends with it) or the exit lane (a lead-out starts with it)
    edges: tuple[str, ...]  # normal edges in the driving direction
    lane_indices: tuple[int, ...]  # SUMO lane index on each of those edges
    lane_starts_m: tuple[float, ...]  # [m] arc length along ``centerline`` where each lane begins
    centerline: FloatArray  # (N, 2) [m] in the driving direction

    @property
    def length_m(self) -> float:
        return polyline_length(self.centerline)

    def stretch_at(self, s_m: float) -> int:
        """Index into ``edges`` of the lane at arc length ``s_m`` (the internal lanes between two
        edges count with the edge before them: SUMO routes from that one)."""
        k = 0
        for i, start in enumerate(self.lane_starts_m):
            if s_m >= start - 1e-9:
                k = i
        return k

    @staticmethod
    def of_lane(lane: Lane) -> LaneChain:
        """The chain of one lane alone."""
        return LaneChain(lane.id, (lane.edge_id,), (lane.index,), (0.0,), lane.centerline)


@dataclass(frozen=True)
class Crossing:
    """A pedestrian crossing over one leg."""

    id: str  # SUMO's crossing edge id
    crossed_edges: tuple[str, ...]
    centerline: FloatArray  # (2+, 2) [m]
    width_m: float
    polygon: Polygon
    tl_link_index: int | None


@dataclass(frozen=True, eq=False)
class Junction:
    """A signalized intersection read from a SUMO network."""

    id: str  # SUMO junction id
    tl_id: str  # id of the traffic light controlling it (may differ from ``id``)
    net_file: Path
    center: FloatArray  # (2,) [m]
    polygon: Polygon  # SUMO's junction shape
    approaches: tuple[Approach, ...]
    lanes: dict[str, Lane]  # every car lane the approaches name (entrance and exit), by id
    drivable_area: BaseGeometry  # junction polygon ∪ car lanes of the approaches and exits, lead-ins, lead-outs
    crossings: tuple[Crossing, ...] = ()
    sidewalks: tuple[Lane, ...] = ()  # pedestrian lanes of the legs
    walking_areas: tuple[Polygon, ...] = ()
    bike_lanes: tuple[Lane, ...] = ()
    exit_edges: tuple[str, ...] = field(default=())  # every edge leaving the junction
    # every SUMO node the junction spans: (id,) for one node, several when SUMO models one
    # signalized intersection as adjacent nodes sharing a traffic light (e.g. a divided road)
    node_ids: tuple[str, ...] = ()
    # entrance lane id → the road before its stop line, ending with the lane (:class:`LaneChain`);
    # exit lane id → the road after its start, starting with the lane. A lane missing here
    # stands alone.
    lead_ins: dict[str, LaneChain] = field(default_factory=dict)
    lead_outs: dict[str, LaneChain] = field(default_factory=dict)

    def lead_in(self, lane_id: str) -> LaneChain:
        """The road towards an entrance lane's stop line (the lane alone when none is traced)."""
        found = self.lead_ins.get(lane_id)
        return found if found is not None else LaneChain.of_lane(self.lanes[lane_id])

    def lead_out(self, lane_id: str) -> LaneChain:
        """The road on from an exit lane's start (the lane alone when none is traced)."""
        found = self.lead_outs.get(lane_id)
        return found if found is not None else LaneChain.of_lane(self.lanes[lane_id])

    def approach(self, edge_id: str) -> Approach:
        for a in self.approaches:
            if a.incoming_edge == edge_id:
                return a
        known = ", ".join(a.incoming_edge for a in self.approaches)
        raise KeyError(f"junction {self.id!r} has no approach {edge_id!r}; approaches: {known}")

    def default_approach(self) -> Approach:
        """The approach whose entrance points most nearly north: the ego comes from the south."""
        return max(self.approaches, key=lambda a: np.sin(a.heading_rad))
