"""Where the ego enters: a given distance before its stop line, along the road it comes in on.

Real nets often end an approach edge 20 m before the stop line (a node where a lane is added, a
previous junction), shorter than the default start of 40 m. The ego then starts that far before
the line along its route, on the edges before its entrance lane (the junction's lead-in,
:class:`crossroads.network.road.LaneChain`), and SUMO routes it from there. Only a network that is
itself too short is refused, naming the longest start that fits.

One rule for every caller: ``crossroads run`` and ``evaluate``, the API and the studio check it
through :mod:`crossroads.scenario.network_checks`, and the world places the ego with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from crossroads.constants import EGO_LENGTH_M
from crossroads.geometry import point_at
from crossroads.network.road import Junction


class StartError(ValueError):
    """The start distance does not fit on the road before the stop line."""


@dataclass(frozen=True)
class EgoPlacement:
    """The ego's start: its centre, its heading and the SUMO route it is inserted on."""

    x: float  # [m] centre of the footprint
    y: float  # [m]
    heading_rad: float
    route_edges: tuple[str, ...]  # from the edge it starts on, through its approach, to its exit
    depart_lane: int  # SUMO lane index on the first of those edges


def longest_start_m(junction: Junction, lane_id: str) -> float:
    """[m] The longest start distance (front bumper to stop line) from entrance lane ``lane_id``:
    the whole ego, its back too, must stand on the road before the stop line (its lead-in)."""
    return junction.lead_in(lane_id).length_m - EGO_LENGTH_M


def start_problem(junction: Junction, lane_id: str, distance_m: float) -> str | None:
    """Why ``distance_m`` [m] before the stop line of ``lane_id`` is no place to start, or None."""
    room = longest_start_m(junction, lane_id)
    if distance_m <= room + 1e-9:
        return None
    lead = junction.lead_in(lane_id)
    edges = " -> ".join(lead.edges)
    return (f"{distance_m:g} m does not fit before the stop line of lane {lane_id!r}: the road "
            f"leading to it ({edges}) is {lead.length_m:.1f} m long, so the ego can start at most "
            f"{max(room, 0.0):.1f} m before the line")


def place_ego(junction: Junction, lane_id: str, distance_m: float, exit_edges: tuple[str, ...]
              ) -> EgoPlacement:
    """The ego's start ``distance_m`` [m] (front bumper) before the stop line of entrance lane
    ``lane_id``, routed on to ``exit_edges`` (the edges after the entrance edge: the junction's
    inner edges, if any, and the exit). Raises :class:`StartError` when it does not fit."""
    problem = start_problem(junction, lane_id, distance_m)
    if problem is not None:
        raise StartError(problem)
    lead = junction.lead_in(lane_id)
    s = max(0.0, lead.length_m - distance_m - EGO_LENGTH_M / 2.0)
    x, y = point_at(lead.centerline, s)
    ahead = point_at(lead.centerline, min(s + 1.0, lead.length_m))
    if math.hypot(*(ahead - (x, y))) < 1e-9:  # at the very end: look back instead
        behind = point_at(lead.centerline, max(s - 1.0, 0.0))
        heading = math.atan2(y - behind[1], x - behind[0])
    else:
        heading = math.atan2(ahead[1] - y, ahead[0] - x)
    k = lead.stretch_at(s)
    return EgoPlacement(float(x), float(y), heading, (*lead.edges[k:], *exit_edges),
                        lead.lane_indices[k])
