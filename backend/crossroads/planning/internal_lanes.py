"""How far SUMO's internal lanes run from the candidate paths of the same movements.

The ego drives its candidate path (the Bezier curve between its entrance and exit lanes); SUMO's
vehicles drive the internal lane of the same connection, and SUMO puts the ego where it projects
onto that lane (``sim/sumo.py``), which is where its junction model and its drivers see it. The
catalogue's builds draw every internal lane along its candidate path (``intersections/build.py``); a
user's net keeps netconvert's, or its author's, lanes, and the further they run from the paths
the less SUMO's idea of the ego is the ego. This measures it, movement by movement, for
``crossroads net check``, the upload answer and the warning of ``crossroads evaluate``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crossroads.constants import INTERNAL_LANE_OFFSET_WARN_M
from crossroads.geometry import FloatArray, distances_to_polyline, hausdorff_distance
from crossroads.network.road import TASKS, Approach, Connection, Junction
from crossroads.planning.drivable import road_check
from crossroads.planning.routes import CandidatePath, PlanningError, build_candidate


@dataclass(frozen=True)
class InternalLaneOffset:
    """One car movement through the junction: SUMO's internal lane against the candidate path.

    ``max_m`` is the Hausdorff distance between the two (the larger of the farthest path point
    from the lane and the farthest lane point from the path), ``mean_m`` the mean distance of the
    path's points from the lane. Both are None when there is nothing to compare: ``problem`` then
    says why (no internal lane, or no candidate path for the pair of lanes).
    """

    approach: str  # incoming edge id
    from_lane: str
    to_lane: str
    turn: str
    via_lane: str | None
    max_m: float | None
    mean_m: float | None
    problem: str | None = None

    @property
    def is_task(self) -> bool:
        """Whether the movement is one the ego may be given (left, straight, right; not a U-turn)."""
        return self.turn in TASKS

    @property
    def above_warning(self) -> bool:
        """Above :data:`INTERNAL_LANE_OFFSET_WARN_M`, on a movement that is a task: the ego never
        drives a U-turn, so how far SUMO's lane of one runs from a Bezier is no concern of it."""
        return self.is_task and self.max_m is not None and self.max_m > INTERNAL_LANE_OFFSET_WARN_M

    def to_json(self) -> dict[str, object]:
        return {"approach": self.approach, "from_lane": self.from_lane, "to_lane": self.to_lane,
                "turn": self.turn, "via_lane": self.via_lane,
                "max_m": None if self.max_m is None else round(self.max_m, 3),
                "mean_m": None if self.mean_m is None else round(self.mean_m, 3),
                "problem": self.problem, "above_warning": self.above_warning}


def movement_offset(junction: Junction, approach: str, conn: Connection,
                    rho: float | None = None) -> InternalLaneOffset:
    """One movement of ``approach``: its internal lane against its candidate path."""
    base = dict(approach=approach, from_lane=conn.from_lane, to_lane=conn.to_lane, turn=conn.turn,
                via_lane=conn.via_lane)
    if conn.via_shape is None or conn.via_lane is None:
        return InternalLaneOffset(**base, max_m=None, mean_m=None,
                                  problem="no internal lane: SUMO moves its vehicles across the "
                                          "junction in one step (a net built with --no-internal-links)")
    missing = [lane for lane in (conn.from_lane, conn.to_lane) if lane not in junction.lanes]
    if missing:
        return InternalLaneOffset(**base, max_m=None, mean_m=None,
                                  problem=f"lane {missing[0]} is not a car lane of the junction's legs")
    try:
        path = build_candidate("check", conn.turn, approach, junction.lanes[conn.from_lane],
                               junction.lanes[conn.to_lane], rho=rho,
                               lead_in=junction.lead_in(conn.from_lane).centerline,
                               lead_out=junction.lead_out(conn.to_lane).centerline,
                               road=road_check(junction, approach))
    except PlanningError as exc:
        return InternalLaneOffset(**base, max_m=None, mean_m=None, problem=f"no candidate path: {exc}")
    max_m, mean_m = path_offset(path, conn.via_shape)
    return InternalLaneOffset(**base, max_m=max_m, mean_m=mean_m)


def path_offset(path: CandidatePath, internal_lane: FloatArray) -> tuple[float, float]:
    """``(max, mean)`` [m]: the Hausdorff distance between the junction part of ``path`` (stop
    line to exit) and SUMO's ``internal_lane`` of the same movement, and the mean distance of
    that part's points from the lane."""
    curve = path.points[(path.s >= path.s_stop_line) & (path.s <= path.s_exit)]
    return (hausdorff_distance(curve, internal_lane),
            float(np.mean(distances_to_polyline(curve, internal_lane))))


def internal_lane_offsets(junction: Junction, rho: float | None = None, approach: Approach | None = None,
                          turn: str | None = None) -> list[InternalLaneOffset]:
    """Every car movement of ``junction`` (of one ``approach`` and one ``turn`` where given), in
    the junction's order."""
    approaches = junction.approaches if approach is None else (approach,)
    return [movement_offset(junction, a.id, c, rho) for a in approaches
            for c in (a.connections if turn is None else a.connections_for(turn))]


def worst_offset(offsets: list[InternalLaneOffset]) -> InternalLaneOffset | None:
    """The task movement (no U-turn) whose internal lane runs furthest from its path (None if
    none compares)."""
    measured = [o for o in offsets if o.max_m is not None and o.is_task]
    return max(measured, key=lambda o: o.max_m or 0.0) if measured else None


def offset_warning(offsets: list[InternalLaneOffset], net_name: str) -> str | None:
    """One sentence for the user when some internal lane runs further off its path than
    :data:`INTERNAL_LANE_OFFSET_WARN_M`, naming the worst movement; None otherwise."""
    above = [o for o in offsets if o.above_warning]
    worst = worst_offset(above)
    if worst is None:
        return None
    tasks = sum(o.is_task for o in offsets)
    return (f"{net_name}: SUMO's internal lanes of {len(above)} of {tasks} car movements run "
            f"more than {INTERNAL_LANE_OFFSET_WARN_M:g} m from the candidate paths, up to "
            f"{worst.max_m:.2f} m ({worst.from_lane} -> {worst.to_lane}, {worst.turn}); SUMO's "
            "vehicles and its junction model see the ego on those lanes, not where it drives. "
            "`crossroads net check` lists every movement.")
