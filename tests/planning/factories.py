"""Synthetic Junctions for the planner and figure tests (no SUMO needed).

``four_way_junction`` builds a regular crossroads with ``n_lanes`` car lanes each way on every
leg, legs at any angles, right-hand traffic, optional medians, crossings and sidewalks.
Import as ``from planning.factories import four_way_junction`` (``tests/`` is on ``sys.path``).

Connections (SUMO-like): the leftmost entrance lane turns left into every exit lane of the left
leg; entrance lane k goes straight into exit lane k of the opposite leg; the rightmost lane turns
right into the rightmost exit lane of the right leg. ``extra`` adds more ``(leg, from_index,
turn, to_index)`` connections.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPoint, Polygon

from crossroads.geometry import unit
from crossroads.network.road import Approach, Connection, Crossing, Junction, Lane, Turn

LANE_WIDTH_M = 3.5
LEG_LENGTH_M = 120.0
SIDEWALK_WIDTH_M = 2.0
CROSSING_WIDTH_M = 4.0


def _right_normal(heading: float) -> np.ndarray:
    return unit(heading - math.pi / 2.0)


def _lane(edge: str, k: int, start: np.ndarray, end: np.ndarray, width: float = LANE_WIDTH_M,
          classes: Iterable[str] = ("passenger", "bus", "truck")) -> Lane:
    return Lane(
        id=f"{edge}_{k}", edge_id=edge, index=k, width_m=width, speed_limit_mps=13.89,
        centerline=np.vstack([start, end]).astype(float), allowed_classes=frozenset(classes),
    )


def four_way_junction(
    n_lanes: int = 2,
    leg_angles_deg: Sequence[float] = (-90.0, 0.0, 90.0, 180.0),
    median_m: float = 0.0,
    extra: Iterable[tuple[int, int, Turn, int]] = (),
    with_crossings: bool = True,
) -> Junction:
    """A 4-leg junction centred at (0, 0); leg i points outward at ``leg_angles_deg[i]``.

    Legs are named by index: incoming edge ``in<i>``, outgoing edge ``out<i>``. Lanes end (start)
    at a distance from the centre that leaves room for the crossings; the junction polygon is the
    convex hull of the lane ends.
    """
    angles = [math.radians(a) for a in leg_angles_deg]
    order = sorted(range(len(angles)), key=lambda i: angles[i] % (2 * math.pi))
    half_road = n_lanes * LANE_WIDTH_M + median_m / 2.0
    # Lanes stop where neighbouring legs no longer overlap (for the narrowest angle), + crossing room.
    gaps = [(angles[order[(j + 1) % 4]] - angles[order[j]]) % (2 * math.pi) for j in range(4)]
    r0 = half_road / math.tan(min(gaps) / 2.0) + half_road * 0.5 + CROSSING_WIDTH_M + 1.0

    lanes: dict[str, Lane] = {}
    legs: list[dict] = []
    for i, a in enumerate(angles):
        out_dir = unit(a)
        in_heading = a + math.pi
        ents, exits = [], []
        for k in range(n_lanes):
            # rightmost (k = 0) is farthest from the leg's axis
            off = (n_lanes - k - 0.5) * LANE_WIDTH_M + median_m / 2.0
            n_in = _right_normal(in_heading) * off
            n_out = _right_normal(a) * off
            ent = _lane(f"in{i}", k, out_dir * (r0 + LEG_LENGTH_M) + n_in, out_dir * r0 + n_in)
            ext = _lane(f"out{i}", k, out_dir * r0 + n_out, out_dir * (r0 + LEG_LENGTH_M) + n_out)
            ents.append(ent)
            exits.append(ext)
            lanes[ent.id] = ent
            lanes[ext.id] = ext
        legs.append({"angle": a, "entrances": ents, "exits": exits})

    def turn_target(i: int, turn: Turn) -> int:
        j = order.index(i)
        step = {"right": 1, "straight": 2, "left": 3}[turn]
        return order[(j + step) % 4]

    approaches = []
    for i, leg in enumerate(legs):
        ents: list[Lane] = leg["entrances"]
        conns: list[Connection] = []

        def add(from_k: int, turn: Turn, to_k: int) -> None:
            target = legs[turn_target(i, turn)]["exits"][to_k]
            conns.append(Connection(ents[from_k].id, target.id, turn, None, None, None))

        for to_k in range(n_lanes):
            add(n_lanes - 1, "left", to_k)
        for k in range(n_lanes):
            add(k, "straight", k)
        add(0, "right", 0)
        for leg_i, from_k, turn, to_k in extra:
            if leg_i == i:
                add(from_k, turn, to_k)
        in_heading = leg["angle"] + math.pi
        ends = [ln.end for ln in ents]
        half = LANE_WIDTH_M / 2.0 * _right_normal(in_heading)
        stop_line = np.vstack([ends[0] + half, ends[-1] - half])
        median = None
        if median_m > 0.0:
            d = unit(leg["angle"])
            nrm = _right_normal(in_heading) * (median_m / 2.0)
            median = Polygon([d * r0 + nrm, d * (r0 + LEG_LENGTH_M) + nrm,
                              d * (r0 + LEG_LENGTH_M) - nrm, d * r0 - nrm])
        approaches.append(Approach(
            incoming_edge=f"in{i}", outgoing_edge=f"out{i}", heading_rad=math.atan2(*unit(in_heading)[::-1]),
            entrance_lanes=tuple(ents), exit_lanes=tuple(leg["exits"]), connections=tuple(conns),
            stop_line=stop_line, median=median,
        ))

    corner_pts = []
    for leg in legs:
        for ln in leg["entrances"] + leg["exits"]:
            p = ln.end if ln.edge_id.startswith("in") else ln.start
            nrm = _right_normal(math.atan2(*(ln.end - ln.start)[::-1])) * (ln.width_m / 2.0)
            corner_pts += [p + nrm, p - nrm]
    polygon = MultiPoint(corner_pts).convex_hull
    car_lanes = [ln.polygon() for ln in lanes.values()]
    # grid_size: GEOS 3.14's plain union_all drops a whole lane of the 30°-rotated layout (lanes
    # sharing an edge up to rounding); snapping to a 1 µm grid makes the overlay robust.
    drivable = shapely.union_all([polygon, *car_lanes], grid_size=1e-6)

    crossings, sidewalks = [], []
    if with_crossings:
        for i, leg in enumerate(legs):
            d = unit(leg["angle"])
            side = _right_normal(leg["angle"])
            rc = r0 - CROSSING_WIDTH_M / 2.0 - 0.5
            w = half_road + SIDEWALK_WIDTH_M / 2.0
            line = np.vstack([d * rc - side * w, d * rc + side * w])
            crossings.append(Crossing(
                id=f":c_{i}", crossed_edges=(f"in{i}", f"out{i}"), centerline=line,
                width_m=CROSSING_WIDTH_M,
                polygon=LineString(line).buffer(CROSSING_WIDTH_M / 2.0, cap_style="flat"),
                tl_link_index=None,
            ))
            for sign, name in ((1.0, "r"), (-1.0, "l")):
                off = side * sign * (half_road + SIDEWALK_WIDTH_M / 2.0)
                sidewalks.append(Lane(
                    id=f"sw{i}{name}_0", edge_id=f"sw{i}{name}", index=0, width_m=SIDEWALK_WIDTH_M,
                    speed_limit_mps=2.0,
                    centerline=np.vstack([d * (r0 - CROSSING_WIDTH_M) + off, d * (r0 + LEG_LENGTH_M) + off]),
                    allowed_classes=frozenset({"pedestrian"}),
                ))

    return Junction(
        id="J", tl_id="J", net_file=Path("synthetic.net.xml"), center=np.zeros(2), polygon=polygon,
        approaches=tuple(approaches), lanes=lanes, drivable_area=drivable,
        crossings=tuple(crossings), sidewalks=tuple(sidewalks),
        exit_edges=tuple(f"out{i}" for i in range(len(legs))),
    )
