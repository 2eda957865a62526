"""Where a participant will drive next: its lanes ahead through the junction, as one centre line.

Static map knowledge (SUMO's connections and their internal lanes) and what a driver reads from a
car's turn signal (the next edge of its route: SUMO's vehicles signal their turns), so a controller
may use it, as it uses the lanes' curvature (``participant_curvatures``). Why: f_other turns a
participant by the curvature of the lane it is on now, so an oncoming left-turner is predicted
straight until it is inside the junction, and the point where it crosses the ego's path jumps
nearer once it turns — on the nominal left turn (150 s, seed 896230294), from 10 m ahead of the ego,
which could still stop, to 6 m, which it no longer could.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import NamedTuple

import numpy as np

from crossroads.constants import DT_S
from crossroads.geometry import FloatArray, arc_lengths, drop_repeated_points
from crossroads.network.model import Approach

# (lane, next edge of the route) -> the lanes that follow it toward that edge: (internal, exit) from
# an entrance lane; (internal lane, "") -> (exit,): an internal lane leads to one lane only
LaneSuccessors = Mapping[tuple[str, str], tuple[str, ...]]


def lane_successors(approaches: Iterable[Approach]) -> dict[tuple[str, str], tuple[str, ...]]:
    """The :data:`LaneSuccessors` of a junction's car connections (the first connection wins where
    one entrance lane reaches several lanes of the same exit edge: they share the way in)."""
    out: dict[tuple[str, str], tuple[str, ...]] = {}
    for approach in approaches:
        for c in approach.connections:
            to_edge = c.to_lane.rsplit("_", 1)[0]
            if c.via_lane:
                out.setdefault((c.from_lane, to_edge), (c.via_lane, c.to_lane))
                out.setdefault((c.via_lane, ""), (c.to_lane,))
            else:
                out.setdefault((c.from_lane, to_edge), (c.to_lane,))
    return out


def next_edge(route: Sequence[str], edge: str) -> str | None:
    """The edge after ``edge`` on ``route``, None at its end or off it."""
    try:
        k = route.index(edge)
    except ValueError:
        return None
    return route[k + 1] if k + 1 < len(route) else None


def lanes_ahead(successors: LaneSuccessors, lane: str, route: Sequence[str]) -> tuple[str, ...]:
    """``lane`` and the lanes its ``route`` takes next (:func:`lane_successors`); on an internal lane
    the one its connection leads to."""
    edge = lane.rsplit("_", 1)[0]
    target = "" if edge.startswith(":") else next_edge(route, edge)
    return (lane,) + (successors.get((lane, target), ()) if target is not None else ())


class CentreLine(NamedTuple):
    """Lanes' centre lines joined, with what projecting onto them needs (computed once: static)."""

    points: FloatArray  # (n ≥ 2, 2)
    cum: FloatArray  # (n,) arc length at each point
    segments: FloatArray  # (n − 1, 2) from each point to the next
    lengths: FloatArray  # (n − 1,) their lengths (≥ 1e-9)


def centre_line(shapes: Mapping[str, FloatArray], lanes: Sequence[str]) -> CentreLine | None:
    """The centre lines of ``lanes`` joined, or None where ``shapes`` does not know the first."""
    shape = shapes.get(lanes[0]) if lanes else None
    if shape is None or len(shape) < 2:
        return None
    points = drop_repeated_points(np.concatenate([shape] + [shapes[k] for k in lanes[1:] if k in shapes]))
    if len(points) < 2:
        return None
    segments = np.diff(points, axis=0)
    return CentreLine(points, arc_lengths(points), segments, np.maximum(np.hypot(*segments.T), 1e-9))


def drive_along(line: CentreLine, x: float, y: float, speed_mps: float, steps: int) -> tuple[FloatArray, FloatArray]:
    """Positions (steps, 2) and headings (steps,) of a participant at (x, y) keeping ``speed_mps``
    along ``line`` from its foot on it, after 1…steps steps of ``DT_S``; past the line's end it
    drives on straight along the last segment."""
    pts, seg, length = line.points, line.segments, line.lengths
    along = np.clip(((x - pts[:-1, 0]) * seg[:, 0] + (y - pts[:-1, 1]) * seg[:, 1]) / (length * length), 0.0, 1.0)
    nearest = int(np.argmin((pts[:-1, 0] + along * seg[:, 0] - x) ** 2 + (pts[:-1, 1] + along * seg[:, 1] - y) ** 2))
    d = line.cum[nearest] + along[nearest] * length[nearest] + speed_mps * DT_S * np.arange(1, steps + 1)
    k = np.clip(np.searchsorted(line.cum, d, side="right") - 1, 0, len(pts) - 2)
    t = (d - line.cum[k]) / length[k]  # > 1 past the end: along the last segment
    return pts[k] + t[:, None] * seg[k], np.arctan2(seg[k, 1], seg[k, 0])
