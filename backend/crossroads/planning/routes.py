"""Candidate paths of the general static path planner (SPEC §1, paper Sec. III-A).

A candidate path is the entrance route X0→X1 along the entrance lane's centre line (X1 on the stop
line, the lane's end), the curve route, a cubic Bezier X1, X2, X3, X4 whose inner control points come
from the paper's closed form (:func:`crossroads.geometry.bezier_control_points_closed_form`), and the
exit route X4→X5 along the exit lane's centre line (X4 the lane's start). One candidate per target
(exit) lane the task can reach from the approach.

Choices (not in the paper):

- **Route lengths.** X0 lies ``entrance_length_m`` = 50 m before the stop line: the 30 m of the
  stop-mode deceleration plus 20 m at cruise speed, more than the 25-step (2.5 s) prediction
  horizon covers at 0.8·V_limit (≈ 21 m). X5 lies ``exit_length_m`` = 30 m after the exit point,
  again beyond that horizon. Both are clamped to the lane (a short lane gives a short route; the
  planner never walks onto neighbouring edges).
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
    cubic_bezier_derivatives,
    drop_repeated_points,
    heading_curvature_from_derivatives,
    headings_and_curvatures,
    polyline_length,
    project_onto_polyline,
    resample,
    sample_cubic_bezier_with_t,
    sub_polyline,
    unit,
    wrap_angle,
)
from crossroads.network.model import TASKS, Approach, Connection, Junction, Lane
from crossroads.planning.speeds import pass_speed, stop_speed

ENTRANCE_LENGTH_M = 50.0  # [m] (choice) X0 → X1 along the entrance lane, clamped to its start
EXIT_LENGTH_M = 30.0  # [m] (choice) X4 → X5 along the exit lane, clamped to its end
SEGMENTS = ("entrance", "curve", "exit")

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

    @property
    def length_m(self) -> float:
        return float(self.s[-1])

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


def build_candidate(
    cid: str,
    task: str,
    approach_id: str,
    entrance: Lane,
    exit_: Lane,
    rho: float = RHO_BEZIER,
    v_limit_mps: float = V_LIMIT_MPS,
    entrance_length_m: float = ENTRANCE_LENGTH_M,
    exit_length_m: float = EXIT_LENGTH_M,
    spacing_m: float = PATH_SAMPLE_SPACING_M,
) -> CandidatePath:
    """The candidate path from the end of ``entrance`` to the start of ``exit_`` (SPEC §1)."""
    ent_line = drop_repeated_points(entrance.centerline)
    ext_line = drop_repeated_points(exit_.centerline)
    ent_len = polyline_length(ent_line)
    entrance_pts = sub_polyline(ent_line, ent_len - entrance_length_m, ent_len)
    exit_pts = sub_polyline(ext_line, 0.0, exit_length_m)
    x0, x1 = entrance_pts[0], entrance_pts[-1]
    x4, x5 = exit_pts[0], exit_pts[-1]
    theta_in, theta_out = entrance.end_heading, exit_.start_heading
    chord = x4 - x1
    if float(np.dot(chord, unit(theta_in))) <= 1e-6 or float(np.dot(chord, unit(theta_out))) <= 1e-6:
        raise PlanningError(
            f"cannot connect {entrance.id} to {exit_.id}: the exit lane starts behind the stop line "
            "or the entrance lies ahead of the exit (the Bezier construction needs X4 ahead of X1 "
            "along both lane directions)"
        )
    x2, x3 = bezier_control_points_closed_form(x1, x4, theta_in, theta_out, rho)
    bez_cp = np.vstack([x1, x2, x3, x4])

    e_pts, e_head, e_curv = _lane_route(entrance_pts, spacing_m)
    c_pts, t = sample_cubic_bezier_with_t(bez_cp, spacing_m)
    c_head, c_curv = heading_curvature_from_derivatives(*cubic_bezier_derivatives(bez_cp, t))
    x_pts, x_head, x_curv = _lane_route(exit_pts, spacing_m)

    points = np.vstack([e_pts, c_pts[1:], x_pts[1:]])
    heading = np.concatenate([e_head, c_head[1:], x_head[1:]])
    curvature = np.concatenate([e_curv, c_curv[1:], x_curv[1:]])
    segment = np.array(["entrance"] * len(e_pts) + ["curve"] * (len(c_pts) - 1) + ["exit"] * (len(x_pts) - 1))
    s = arc_lengths(points)
    s_stop_line = float(s[len(e_pts) - 1])
    s_exit = float(s[len(e_pts) + len(c_pts) - 2])
    return CandidatePath(
        id=cid,
        task=task,
        approach=approach_id,
        entrance_lane=entrance.id,
        exit_lane=exit_.id,
        control_points=np.vstack([x0, x1, x2, x3, x4, x5]),
        points=points,
        heading=np.asarray(wrap_angle(heading), float),
        curvature=curvature,
        s=s,
        segment=segment,
        s_stop_line=s_stop_line,
        s_exit=s_exit,
        v_pass=np.asarray(pass_speed(s, s_stop_line, s_exit, v_limit_mps), float),
        v_stop=np.asarray(stop_speed(s, s_stop_line, s_exit, v_limit_mps), float),
    )


def plan_candidates(
    junction: Junction,
    task: str,
    approach: Approach | str | None = None,
    rho: float = RHO_BEZIER,
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
        rho: ρ ∈ (0, 1) of the Bezier construction (0.6 in the paper).
        v_limit_mps: V_limit of the velocity planning [m/s].
        entrance_length_m: length of the entrance route X0→X1 [m] (> 0; clamped to the lane).
        exit_length_m: length of the exit route X4→X5 [m] (> 0; clamped to the lane).
        entrance_lane: plan only from this entrance lane (default: choose per target lane).

    Returns:
        One :class:`CandidatePath` per reachable target lane, right to left, ids "<task>-0", ...

    Raises:
        PlanningError: unknown task or approach, no connection for the task, ρ outside (0, 1),
            non-positive lengths or speed limit, or a geometry the construction cannot connect.
    """
    if not (isinstance(rho, (int, float)) and 0.0 < rho < 1.0):
        raise PlanningError(f"rho must lie in (0, 1), got {rho!r}")
    for name, value in (("entrance_length_m", entrance_length_m), ("exit_length_m", exit_length_m),
                        ("v_limit_mps", v_limit_mps)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
            raise PlanningError(f"{name} must be a positive number, got {value!r}")
    chosen = _resolve_approach(junction, approach)
    movements = select_movements(junction, chosen, task, entrance_lane)
    return [
        build_candidate(
            f"{task}-{k}", task, chosen.id,
            _lane(junction, chosen, c.from_lane), _lane(junction, chosen, c.to_lane),
            rho=rho, v_limit_mps=v_limit_mps,
            entrance_length_m=entrance_length_m, exit_length_m=exit_length_m,
        )
        for k, c in enumerate(movements)
    ]
