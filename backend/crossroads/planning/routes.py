"""Candidate paths of the general static path planner (SPEC §1, paper Sec. III-A).

A candidate path is the entrance route X0→X1 along the entrance lane's centre line (X1 on the stop
line, the lane's end), the curve route, a cubic Bezier X1, X2, X3, X4 whose inner control points come
from the paper's closed form (:func:`crossroads.geometry.bezier_control_points_closed_form`), and the
exit route X4→X5 along the exit lane's centre line (X4 the lane's start). One candidate per target
(exit) lane the task can reach from the approach.

Choices (not in the paper):

- **ρ per candidate** (:mod:`crossroads.planning.curves`): the paper's ρ = 0.6 where its curve
  bends gently enough, otherwise the ρ whose curve bends least, so that the ego (at most
  0.16 1/m) can drive it. ``rho=`` fixes one ρ for every candidate (the paper's construction).
- **Moving X1 and X4**: where no ρ keeps the curve within the steering limit, X1 moves back along
  the entrance and X4 on along the exit lane (:data:`ENDPOINT_SHIFT_STEP_M` steps, up to
  :data:`ENDPOINT_SHIFT_MAX_M` each; the smallest total move that works). The stop line and the
  exit lane's start (``s_stop_line``, ``s_exit``, which the speed profiles use) stay where they are:
  the curve then starts before the line or ends after the exit lane's start (the pass mode's inside
  speed then holds over the whole curve, X1 to X4). Where no curve gets
  within the limit, the movement is refused, naming how much the least bent curve bends (a kerb
  drawn too tight for a car): a candidate is one a car can drive, or none. With a fixed ρ every
  candidate is drawn as asked, and :class:`TaskPlan` warns of those over the limit.
- **On the road** (:mod:`crossroads.planning.drivable`): a curve whose footprint leaves the
  drivable area, or that runs over another approach's entrance lanes, is not offered; its movement
  is refused with the reason (:class:`Refusal`), and a task whose every movement is refused raises
  :class:`PlanningError` with the first reason.
- **Route lengths.** X0 lies ``entrance_length_m`` = 50 m before X1: the 30 m of the stop-mode
  deceleration plus 20 m at cruise speed, more than the 25-step (2.5 s) prediction horizon covers
  at 0.8·V_limit (≈ 21 m). The entrance route runs over the lanes before the entrance lane where
  that lane is shorter (the junction's lead-in, :class:`crossroads.network.road.LaneChain`): real
  nets often end an approach edge 20 m before the stop line. X5 lies ``exit_length_m`` = 30 m after
  X4, again beyond that horizon, over the lanes after the exit lane where it is shorter (its
  lead-out: an OSM import may leave a 0.2 m stub); both clamped to where the road is traced.
- **Which entrance lane serves a target lane.** When several entrance lanes connect to one target
  lane, the candidate starts on the entrance lane whose lateral order matches the target's: the
  entrance lanes and target lanes of the task are each ranked right to left, normalised to [0, 1],
  and the closest normalised rank wins (ties: the rightmost entrance lane). This is how vehicles
  turn side by side and keeps the candidates of one task from crossing each other. Pass
  ``entrance_lane`` to plan only from one lane (e.g. the lane the ego is in).
- **Sampling.** Every route is sampled at ≤ ``PATH_SAMPLE_SPACING_M`` (0.5 m); the joins X1 and X4
  appear once. Heading and curvature are exact on the Bezier (from its derivatives); on the lane
  routes they come from finite differences of the resampled centre line. Heading is continuous at
  X1 and X4 by construction (X2 lies on the entrance line ahead of X1, X3 on the exit line behind
  X4). Curvature is not: the paper's Bezier starts and ends with non-zero curvature, so it jumps
  at X1 and X4 (bounded, no spikes).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from crossroads.constants import PATH_SAMPLE_SPACING_M, RHO_BEZIER, V_LIMIT_MPS
from crossroads.geometry import (
    FloatArray,
    arc_lengths,
    bezier_control_points_closed_form,
    cubic_bezier,
    cubic_bezier_derivatives,
    drop_repeated_points,
    heading_curvature_from_derivatives,
    heading_of,
    headings_and_curvatures,
    point_at,
    polyline_length,
    project_onto_polyline,
    resample,
    sample_cubic_bezier_with_t,
    sub_polyline,
    unit,
    wrap_angle,
)
from crossroads.network.road import TASKS, Approach, Connection, Junction, Lane
from crossroads.planning.curves import CURVATURE_TOLERANCE, MAX_CURVATURE, rho_preferences
from crossroads.planning.drivable import RoadCheck, road_check
from crossroads.planning.speeds import pass_speed, stop_speed

ENTRANCE_LENGTH_M = 50.0  # [m] (choice) X0 → X1 along the entrance lane, clamped to its start
EXIT_LENGTH_M = 30.0  # [m] (choice) X4 → X5 along the exit lane, clamped to its end
SEGMENTS = ("entrance", "curve", "exit")
# Moving X1 back and X4 on (choice): only where no ρ keeps the curve within the steering limit, in
# steps of 2.5 m up to 10 m each (two car lengths: beyond, the curve would begin or end where no
# driver turns), keeping 1 m of lane beyond each end; the smallest total move that fits wins.
ENDPOINT_SHIFT_MAX_M = 10.0  # [m]
ENDPOINT_SHIFT_STEP_M = 2.5  # [m]
ENDPOINT_ROOM_M = 1.0  # [m]
RHO_TRIES = 12  # ρ tried per X1, X4 before the next move (each try costs one road check)

_TASK_WORDS = {"left": "left-turn", "straight": "straight", "right": "right-turn", "uturn": "u-turn"}


class PlanningError(ValueError):
    """The planner cannot build the candidates asked for (unknown task, no connection, bad ρ)."""


class PathProjection(NamedTuple):
    """Where a point lies relative to a candidate path."""

    index: int  # index of the path segment (points[index] → points[index + 1]) it projects onto
    s_m: float  # arc length of the foot point from X0 [m]
    lateral_m: float  # signed offset from the path, positive to the left of the driving direction [m]
    heading_rad: float  # path heading at the foot point [rad]


@dataclass(frozen=True, eq=False)
class CandidatePath:
    """One candidate path τ: geometry sampled at ≤ 0.5 m and its pass/stop speed references.

    All per-point arrays have the length N of ``points``.
    """

    id: str  # "<task>-<k>", k counting the target lanes right to left
    task: str  # "left" | "straight" | "right"
    approach: str  # incoming edge id
    entrance_lane: str  # lane id of the entrance route
    exit_lane: str  # lane id of the exit route (the target lane)
    control_points: FloatArray  # (6, 2) X0..X5 [m]
    points: FloatArray  # (N, 2) [m]
    heading: FloatArray  # (N,) [rad], CCW from +x, wrapped into [-π, π)
    curvature: FloatArray  # (N,) [1/m], positive turning left
    s: FloatArray  # (N,) arc length from X0 [m]
    segment: np.ndarray  # (N,) "entrance" | "curve" | "exit"
    s_stop_line: float  # arc length of X1 [m]
    s_exit: float  # arc length of X4 [m]
    v_pass: FloatArray  # (N,) pass-mode reference speed [m/s]
    v_stop: FloatArray  # (N,) stop-mode reference speed [m/s]
    rho: float = RHO_BEZIER  # [-] ρ the curve route was drawn with
    max_curvature: float = 0.0  # [1/m] largest |curvature| of the curve route X1 → X4
    x1_shift_m: float = 0.0  # [m] X1 moved back from the stop line along the entrance (see module doc)
    x4_shift_m: float = 0.0  # [m] X4 moved on from the exit lane's start along it

    @property
    def length_m(self) -> float:
        return float(self.s[-1])

    @property
    def exceeds_limit(self) -> bool:
        """Whether the curve bends tighter than the ego can steer (:data:`MAX_CURVATURE`)."""
        return self.max_curvature > MAX_CURVATURE + CURVATURE_TOLERANCE

    def nearest(self, x: float, y: float) -> int:
        """Index of the sampled point nearest to (x, y)."""
        return int(np.argmin(np.hypot(self.points[:, 0] - x, self.points[:, 1] - y)))

    def project(self, x: float, y: float) -> PathProjection:
        """Foot of (x, y) on the path: segment index, arc length, signed lateral offset, heading.

        Beyond either end the arc length is clamped and the offset is taken from the extended end
        segment. The heading is interpolated along the segment (across ±π correctly).
        """
        i, s, lateral = project_onto_polyline(self.points, (x, y))
        seg = self.s[i + 1] - self.s[i]
        w = 0.0 if seg <= 0.0 else min(max((s - self.s[i]) / seg, 0.0), 1.0)
        h0 = self.heading[i]
        h = h0 + w * wrap_angle(self.heading[i + 1] - h0)
        return PathProjection(i, s, lateral, float(wrap_angle(h)))

    def reference_at(self, s_m: float, mode: str = "pass") -> tuple[float, float, float, float]:
        """Reference (x [m], y [m], heading [rad], speed [m/s]) at arc length ``s_m`` (clamped)."""
        s_m = min(max(s_m, 0.0), self.length_m)
        # interpolate on the stored arc lengths (called every control step: no recomputation)
        i = int(np.clip(np.searchsorted(self.s, s_m, side="right") - 1, 0, len(self.s) - 2))
        seg = self.s[i + 1] - self.s[i]
        w = 0.0 if seg <= 0.0 else (s_m - self.s[i]) / seg
        x, y = self.points[i] + w * (self.points[i + 1] - self.points[i])
        h = float(wrap_angle(self.heading[i] + w * wrap_angle(self.heading[i + 1] - self.heading[i])))
        if mode not in ("pass", "stop"):
            raise ValueError(f"unknown speed mode {mode!r}; expected 'pass' or 'stop'")
        # the profile as sampled, interpolated like the position (a step of the pass profile
        # becomes a ramp over one 0.5 m sample, which no controller notices)
        profile = self.v_pass if mode == "pass" else self.v_stop
        v = profile[i] + w * (profile[i + 1] - profile[i])
        return float(x), float(y), h, float(v)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict (plain lists; coordinates to the millimetre)."""
        rows = np.column_stack([self.points, self.heading, self.curvature, self.s])
        return {
            "id": self.id,
            "task": self.task,
            "approach": self.approach,
            "entrance_lane": self.entrance_lane,
            "exit_lane": self.exit_lane,
            "control_points": np.round(self.control_points, 3).tolist(),
            "points": [[round(float(v), d) for v, d in zip(r, (3, 3, 5, 5, 3))] for r in rows],
            "segment": [str(x) for x in self.segment],
            "s_stop_line": round(self.s_stop_line, 3),
            "s_exit": round(self.s_exit, 3),
            "v_pass": np.round(self.v_pass, 3).tolist(),
            "v_stop": np.round(self.v_stop, 3).tolist(),
            "rho": round(self.rho, 3),
            "max_curvature": round(self.max_curvature, 4),
            "exceeds_limit": self.exceeds_limit,
            "x1_shift_m": round(self.x1_shift_m, 3),
            "x4_shift_m": round(self.x4_shift_m, 3),
        }


# --- Choosing the movements -----------------------------------------------------------------------


def _resolve_approach(junction: Junction, approach: Approach | str | None) -> Approach:
    if approach is None:
        return junction.default_approach()
    if isinstance(approach, Approach):
        return approach
    try:
        return junction.approach(approach)
    except KeyError as exc:
        raise PlanningError(exc.args[0]) from None


def _lane(junction: Junction, approach: Approach, lane_id: str) -> Lane:
    for lane in approach.entrance_lanes:
        if lane.id == lane_id:
            return lane
    if lane_id in junction.lanes:
        return junction.lanes[lane_id]
    raise PlanningError(f"junction {junction.id!r} has no geometry for lane {lane_id!r}")


def _rank(ids: Sequence[str], lane_index: dict[str, tuple[str, int]]) -> dict[str, float]:
    """Normalised right-to-left rank in [0, 1] of each lane id (0 = rightmost)."""
    ordered = sorted(ids, key=lambda i: (lane_index[i][1], i))
    n = len(ordered)
    return {lane_id: (k / (n - 1) if n > 1 else 0.5) for k, lane_id in enumerate(ordered)}


def select_movements(
    junction: Junction, approach: Approach, task: str, entrance_lane: str | None = None
) -> list[Connection]:
    """One connection per target lane of ``task``: the entrance lane serving each target lane.

    Targets are ordered right to left (SUMO lane index 0 first). See the module docstring for how
    one entrance lane is chosen among several.
    """
    if task not in TASKS:
        raise PlanningError(f"unknown task {task!r}; expected one of {', '.join(TASKS)}")
    conns = list(approach.connections_for(task))  # type: ignore[arg-type]
    if entrance_lane is not None:
        known = {lane.id for lane in approach.entrance_lanes} | {c.from_lane for c in approach.connections}
        if entrance_lane not in known:
            raise PlanningError(f"lane {entrance_lane!r} is not an entrance lane of approach {approach.id!r}")
        conns = [c for c in conns if c.from_lane == entrance_lane]
    if not conns:
        allowed = [t for t in TASKS if approach.connections_for(t)]  # type: ignore[arg-type]
        where = f"approach {approach.id}" + (f" (lane {entrance_lane})" if entrance_lane else "")
        if entrance_lane:
            allowed = sorted(approach.turns_of(entrance_lane), key=lambda t: (t not in TASKS, t))
        raise PlanningError(
            f"{where} has no {_TASK_WORDS[task]} connection; it allows: {', '.join(allowed) or 'nothing'}"
        )
    index: dict[str, tuple[str, int]] = {}
    for c in conns:
        for lane_id in (c.from_lane, c.to_lane):
            lane = junction.lanes.get(lane_id) or next(
                (la for la in approach.entrance_lanes if la.id == lane_id), None
            )
            if lane is None:
                raise PlanningError(f"junction {junction.id!r} has no geometry for lane {lane_id!r}")
            index[lane_id] = (lane.edge_id, lane.index)
    from_rank = _rank(sorted({c.from_lane for c in conns}), index)
    to_rank = _rank(sorted({c.to_lane for c in conns}), index)

    def preference(c: Connection) -> tuple[float, float]:  # smaller is better
        return abs(from_rank[c.from_lane] - to_rank[c.to_lane]), from_rank[c.from_lane]

    chosen: dict[str, Connection] = {}
    for c in conns:
        if c.to_lane not in chosen or preference(c) < preference(chosen[c.to_lane]):
            chosen[c.to_lane] = c
    return sorted(chosen.values(), key=lambda c: (index[c.to_lane][0], index[c.to_lane][1], c.to_lane))


# --- Building one path ----------------------------------------------------------------------------


def _lane_route(points: FloatArray, spacing_m: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Resampled lane route with finite-difference heading and curvature."""
    pts = resample(points, spacing_m)
    if len(pts) < 2:
        raise PlanningError("a lane route of zero length")
    heading, curvature = headings_and_curvatures(pts)
    return pts, np.asarray(heading, float), np.asarray(curvature, float)


def _heading_at(line: FloatArray, s_m: float) -> float:
    """Heading [rad] of a polyline at arc length ``s_m``: its segment there (the last segment at
    the end, the first at the start: the lane's own end and start headings)."""
    cum = arc_lengths(line)
    i = int(np.clip(np.searchsorted(cum, s_m, side="right") - 1, 0, len(line) - 2))
    if s_m >= cum[-1] - 1e-9:
        i = len(line) - 2
    return heading_of(line[i + 1] - line[i])


class _Ends(NamedTuple):
    """X1 and X4 of one try: where the curve leaves the entrance and joins the exit."""

    s1: float  # [m] arc length of X1 along the entrance line
    s4: float  # [m] arc length of X4 along the exit line
    x1: FloatArray
    x4: FloatArray
    theta_in: float
    theta_out: float


def _ends(ent_line: FloatArray, ext_line: FloatArray, shift_in: float, shift_out: float,
          entrance_id: str, exit_id: str) -> _Ends:
    s1 = polyline_length(ent_line) - shift_in
    x1, x4 = point_at(ent_line, s1), point_at(ext_line, shift_out)
    theta_in, theta_out = _heading_at(ent_line, s1), _heading_at(ext_line, shift_out)
    chord = x4 - x1
    if float(np.dot(chord, unit(theta_in))) <= 1e-6 or float(np.dot(chord, unit(theta_out))) <= 1e-6:
        raise PlanningError(
            f"cannot connect {entrance_id} to {exit_id}: the exit lane starts behind the stop line "
            "or the entrance lies ahead of the exit (the Bezier construction needs X4 ahead of X1 "
            "along both lane directions)"
        )
    return _Ends(s1, shift_out, x1, x4, theta_in, theta_out)


def _control_points(ends: _Ends, rho: float) -> FloatArray:
    x2, x3 = bezier_control_points_closed_form(ends.x1, ends.x4, ends.theta_in, ends.theta_out, rho)
    return np.vstack([ends.x1, x2, x3, ends.x4])


_T_CHECK = np.linspace(0.0, 1.0, 121)  # curve samples the road check looks at (≤ 0.3 m apart on ~35 m)


def _road_problem(road: RoadCheck, cp: FloatArray, detail: bool = True) -> str | None:
    """What :class:`RoadCheck` says of the curve drawn on ``cp``; without ``detail`` only
    whether it has something to say (``"off the road"``), which is quicker."""
    d1, d2 = cubic_bezier_derivatives(cp, _T_CHECK)
    try:
        heading, _ = heading_curvature_from_derivatives(d1, d2)
    except ValueError as exc:  # a cusp: no direction to drive in somewhere
        return str(exc)
    points = cubic_bezier(cp, _T_CHECK)
    if not detail:
        return None if road.fits(points, heading) else "off the road"
    return road.problem(points, heading)


def _shifts(ent_len: float, ext_len: float) -> list[tuple[float, float]]:
    """(X1 back, X4 on) [m] pairs to try, smallest total move first (the paper's ends first)."""
    steps = np.arange(0.0, ENDPOINT_SHIFT_MAX_M + 1e-9, ENDPOINT_SHIFT_STEP_M)
    pairs = [(float(a), float(b)) for a in steps for b in steps
             if a <= ent_len - ENDPOINT_ROOM_M and b <= ext_len - ENDPOINT_ROOM_M]
    return sorted(pairs, key=lambda p: (p[0] + p[1], p[0])) or [(0.0, 0.0)]


def _choose_curve(ent_line: FloatArray, ext_line: FloatArray, entrance_id: str, exit_id: str,
                  rho: float | None, road: RoadCheck | None) -> tuple[_Ends, float]:
    """X1, X4 and ρ of the curve route (see the module docstring); PlanningError with the reason
    when no curve tried is one a car can drive: none keeps to the road, or (ρ chosen) none that
    does stays within the ego's steering limit."""
    if rho is not None:  # the paper's construction with a fixed ρ: the lane ends, nothing moved
        ends = _ends(ent_line, ext_line, 0.0, 0.0, entrance_id, exit_id)
        problem = None if road is None else _road_problem(road, _control_points(ends, rho))
        if problem is not None:
            raise PlanningError(f"{entrance_id} -> {exit_id} (rho {rho:g}): {problem}")
        return ends, rho
    least: tuple[float, float, float] | None = None  # (max κ, X1 back, X4 on) of the least bent fitting curve
    off_road: FloatArray | None = None  # control points of the first curve off the road (for the message)
    shape_problem: str | None = None
    for shift_in, shift_out in _shifts(polyline_length(ent_line), polyline_length(ext_line)):
        try:
            ends = _ends(ent_line, ext_line, shift_in, shift_out, entrance_id, exit_id)
        except PlanningError as exc:
            shape_problem = shape_problem or str(exc)
            continue
        for tries, choice in enumerate(rho_preferences(ends.x1, ends.x4, ends.theta_in, ends.theta_out)):
            if tries >= RHO_TRIES or (least is not None and choice.max_curvature >= least[0]):
                break
            cp = _control_points(ends, choice.rho)
            if road is not None and _road_problem(road, cp, detail=False) is not None:
                off_road = cp if off_road is None else off_road
                continue
            if choice.within_limit:
                return ends, choice.rho
            least = (choice.max_curvature, shift_in, shift_out)
            break  # the later choices of this X1, X4 bend more
    if least is not None:
        kappa, shift_in, shift_out = least
        raise PlanningError(
            f"{entrance_id} -> {exit_id}: no curve a car can drive: the least bent one that keeps to "
            f"the road bends {kappa:.3f} 1/m (X1 back {shift_in:g} m, X4 on {shift_out:g} m), tighter "
            f"than the ego can steer ({MAX_CURVATURE:.3f} 1/m)")
    if off_road is None or road is None:  # no X1, X4 in reach the construction can join
        raise PlanningError(str(shape_problem))
    raise PlanningError(f"{entrance_id} -> {exit_id}: no curve keeps to the road: "
                        f"{_road_problem(road, off_road)}")


def build_candidate(
    cid: str,
    task: str,
    approach_id: str,
    entrance: Lane,
    exit_: Lane,
    rho: float | None = None,
    v_limit_mps: float = V_LIMIT_MPS,
    entrance_length_m: float = ENTRANCE_LENGTH_M,
    exit_length_m: float = EXIT_LENGTH_M,
    spacing_m: float = PATH_SAMPLE_SPACING_M,
    *,
    lead_in: FloatArray | None = None,
    lead_out: FloatArray | None = None,
    road: RoadCheck | None = None,
) -> CandidatePath:
    """The candidate path from the end of ``entrance`` to the start of ``exit_`` (SPEC §1).

    ``rho``: the paper's ρ for the curve route, or None to choose it (and, where needed, X1 and X4)
    so that the curve stays within :data:`MAX_CURVATURE` (module docstring). ``lead_in``: the road
    before the stop line, ending there (default: the entrance lane alone); ``lead_out``: the road
    on from the exit lane's start (default: the exit lane alone). ``road``: the check the
    curve must pass (:class:`~crossroads.planning.drivable.RoadCheck`; default: none).
    Raises :class:`PlanningError` when no curve can join the lanes (or none passes ``road``).
    """
    ent_line = drop_repeated_points(entrance.centerline if lead_in is None else lead_in)
    ext_line = drop_repeated_points(exit_.centerline if lead_out is None else lead_out)
    ends, rho_used = _choose_curve(ent_line, ext_line, entrance.id, exit_.id, rho, road)
    entrance_pts = sub_polyline(ent_line, ends.s1 - entrance_length_m, ends.s1)
    exit_pts = sub_polyline(ext_line, ends.s4, ends.s4 + exit_length_m)
    x0, x5 = entrance_pts[0], exit_pts[-1]
    bez_cp = _control_points(ends, rho_used)

    e_pts, e_head, e_curv = _lane_route(entrance_pts, spacing_m)
    c_pts, t = sample_cubic_bezier_with_t(bez_cp, spacing_m)
    c_head, c_curv = heading_curvature_from_derivatives(*cubic_bezier_derivatives(bez_cp, t))
    x_pts, x_head, x_curv = _lane_route(exit_pts, spacing_m)

    points = np.vstack([e_pts, c_pts[1:], x_pts[1:]])
    heading = np.concatenate([e_head, c_head[1:], x_head[1:]])
    curvature = np.concatenate([e_curv, c_curv[1:], x_curv[1:]])
    segment = np.array(["entrance"] * len(e_pts) + ["curve"] * (len(c_pts) - 1) + ["exit"] * (len(x_pts) - 1))
    s = arc_lengths(points)
    s_x1 = float(s[len(e_pts) - 1])
    s_x4 = float(s[len(e_pts) + len(c_pts) - 2])
    shift_in = polyline_length(ent_line) - ends.s1
    # the stop line and the exit lane's start, where X1 and X4 moved off them
    s_stop_line = s_x1 if shift_in <= 0.0 else project_onto_polyline(points, ent_line[-1])[1]
    s_exit = s_x4 if ends.s4 <= 0.0 else project_onto_polyline(points, ext_line[0])[1]
    s_exit = max(s_exit, s_stop_line)
    return CandidatePath(
        id=cid,
        task=task,
        approach=approach_id,
        entrance_lane=entrance.id,
        exit_lane=exit_.id,
        control_points=np.vstack([x0, *bez_cp, x5]),
        points=points,
        heading=np.asarray(wrap_angle(heading), float),
        curvature=curvature,
        s=s,
        segment=segment,
        s_stop_line=s_stop_line,
        s_exit=s_exit,
        # the inside speed over the whole curve: from X1 where it moved before the stop line, to
        # X4 where it moved past the exit lane's start (a curve is no place for cruise speed)
        v_pass=np.asarray(pass_speed(s, min(s_x1, s_stop_line), max(s_x4, s_exit), v_limit_mps), float),
        v_stop=np.asarray(stop_speed(s, s_stop_line, max(s_x4, s_exit), v_limit_mps), float),
        rho=float(rho_used),
        max_curvature=float(np.abs(c_curv).max()),
        x1_shift_m=float(shift_in),
        x4_shift_m=float(ends.s4),
    )


# --- Every candidate of a task --------------------------------------------------------------------


@dataclass(frozen=True)
class Refusal:
    """A movement of the task that gets no candidate path, and why."""

    entrance_lane: str
    exit_lane: str
    reason: str

    def to_json(self) -> dict[str, str]:
        return {"entrance_lane": self.entrance_lane, "exit_lane": self.exit_lane, "reason": self.reason}


@dataclass(frozen=True)
class TaskPlan:
    """The candidate paths of a task and the movements refused one."""

    task: str
    candidates: tuple[CandidatePath, ...]
    refused: tuple[Refusal, ...] = ()
    rho: float | None = None  # the fixed ρ asked for, or None: chosen per candidate

    def require(self) -> list[CandidatePath]:
        """The candidates; :class:`PlanningError` (one line, the first reason) when there are none."""
        if not self.candidates:
            first = self.refused[0]
            more = f" (and {len(self.refused) - 1} more movement(s))" if len(self.refused) > 1 else ""
            raise PlanningError(f"no drivable {_TASK_WORDS[self.task]} path: {first.reason}{more}")
        return list(self.candidates)

    @property
    def warnings(self) -> list[str]:
        """One sentence per refused movement and per candidate bending tighter than the ego can
        (only with a fixed ρ: a chosen one refuses such a movement)."""
        out = [f"no candidate into {r.exit_lane} (from {r.entrance_lane}): {r.reason}" for r in self.refused]
        out += [f"candidate {c.id} ({c.entrance_lane} -> {c.exit_lane}) bends up to "
                f"{c.max_curvature:.3f} 1/m, tighter than the ego can steer ({MAX_CURVATURE:.3f} 1/m): "
                f"drawn with the fixed rho {self.rho:g}" for c in self.candidates if c.exceeds_limit]
        return out


def plan_task(
    junction: Junction,
    task: str,
    approach: Approach | str | None = None,
    rho: float | None = None,
    v_limit_mps: float = V_LIMIT_MPS,
    entrance_length_m: float = ENTRANCE_LENGTH_M,
    exit_length_m: float = EXIT_LENGTH_M,
    entrance_lane: str | None = None,
) -> TaskPlan:
    """The candidate paths of ``task`` from ``approach`` and the movements refused one; arguments
    as :func:`plan_candidates`. Raises :class:`PlanningError` as it does, except when every
    movement is refused (the plan then has no candidates and says why)."""
    if rho is not None and not (isinstance(rho, (int, float)) and 0.0 < rho < 1.0):
        raise PlanningError(f"rho must lie in (0, 1), got {rho!r}")
    for name, value in (("entrance_length_m", entrance_length_m), ("exit_length_m", exit_length_m),
                        ("v_limit_mps", v_limit_mps)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
            raise PlanningError(f"{name} must be a positive number, got {value!r}")
    chosen = _resolve_approach(junction, approach)
    movements = select_movements(junction, chosen, task, entrance_lane)
    road = road_check(junction, chosen.id)
    candidates: list[CandidatePath] = []
    refused: list[Refusal] = []
    for k, c in enumerate(movements):
        entrance = _lane(junction, chosen, c.from_lane)
        lead_in = junction.lead_in(c.from_lane).centerline if c.from_lane in junction.lanes else None
        lead_out = junction.lead_out(c.to_lane).centerline if c.to_lane in junction.lanes else None
        try:
            candidates.append(build_candidate(
                f"{task}-{k}", task, chosen.id, entrance, _lane(junction, chosen, c.to_lane),
                rho=rho, v_limit_mps=v_limit_mps,
                entrance_length_m=entrance_length_m, exit_length_m=exit_length_m,
                lead_in=lead_in, lead_out=lead_out, road=road,
            ))
        except PlanningError as exc:
            refused.append(Refusal(c.from_lane, c.to_lane, str(exc)))
    return TaskPlan(task, tuple(candidates), tuple(refused), rho)


def plan_candidates(
    junction: Junction,
    task: str,
    approach: Approach | str | None = None,
    rho: float | None = None,
    v_limit_mps: float = V_LIMIT_MPS,
    entrance_length_m: float = ENTRANCE_LENGTH_M,
    exit_length_m: float = EXIT_LENGTH_M,
    entrance_lane: str | None = None,
) -> list[CandidatePath]:
    """Every candidate path of ``task`` from ``approach`` (default: from the south).

    Args:
        junction: the intersection.
        task: "left", "straight" or "right".
        approach: an :class:`Approach`, its incoming edge id, or None for
            ``junction.default_approach()``.
        rho: ρ ∈ (0, 1) of the Bezier construction for every candidate (the paper: 0.6), or None
            to choose it per candidate within the ego's steering limit (module docstring).
        v_limit_mps: V_limit of the velocity planning [m/s].
        entrance_length_m: length of the entrance route X0→X1 [m] (> 0; clamped to the road).
        exit_length_m: length of the exit route X4→X5 [m] (> 0; clamped to the lane).
        entrance_lane: plan only from this entrance lane (default: choose per target lane).

    Returns:
        One :class:`CandidatePath` per reachable target lane whose curve keeps to the road, right
        to left, ids "<task>-<k>" with k the target lane's rank (a refused one leaves its k out;
        :func:`plan_task` says why).

    Raises:
        PlanningError: unknown task or approach, no connection for the task, ρ outside (0, 1),
            non-positive lengths or speed limit, or no movement of the task with a curve that
            keeps to the road (the message gives the first reason).
    """
    return plan_task(junction, task, approach, rho, v_limit_mps, entrance_length_m,
                     exit_length_m, entrance_lane).require()
