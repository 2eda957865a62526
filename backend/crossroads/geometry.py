"""Pure geometry: polylines, headings, the paper's Bezier construction.

Conventions: points are ``(x, y)`` in metres in SUMO's network frame (x east, y north); headings
are radians, counter-clockwise from +x (the paper's θ). Polylines are ``(N, 2)`` float arrays.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def as_points(points: ArrayLike) -> FloatArray:
    """Return ``points`` as a float ``(N, 2)`` array, rejecting any other shape."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"expected an (N, 2) array of points, got shape {arr.shape}")
    return arr


def unit(angle_rad: float) -> FloatArray:
    """Unit direction vector of a heading."""
    return np.array([math.cos(angle_rad), math.sin(angle_rad)])


def heading_of(vector: ArrayLike) -> float:
    """Heading of a 2-D vector [rad]."""
    v = np.asarray(vector, dtype=np.float64)
    return math.atan2(float(v[1]), float(v[0]))


def wrap_angle(angle_rad):
    """Wrap an angle, or an array of angles, into [-π, π)."""
    wrapped = (np.asarray(angle_rad, dtype=np.float64) + np.pi) % (2.0 * np.pi) - np.pi
    return float(wrapped) if wrapped.ndim == 0 else wrapped


def wrap_scalar(angle_rad: float) -> float:
    """:func:`wrap_angle` of one Python float, without numpy's per-call cost (for per-step hot paths;
    Python's % is numpy's mod: the same result)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def sumo_angle_to_heading(angle_deg: float) -> float:
    """SUMO's navigational angle (degrees, clockwise from north) to our heading (rad, CCW from +x)."""
    return float(wrap_angle(math.radians(90.0 - angle_deg)))


def heading_to_sumo_angle(heading_rad: float) -> float:
    """Our heading (rad, CCW from +x) to SUMO's navigational angle in [0, 360)."""
    return (90.0 - math.degrees(heading_rad)) % 360.0


def arc_lengths(polyline: ArrayLike) -> FloatArray:
    """Cumulative arc length at every vertex, starting at 0."""
    pts = as_points(polyline)
    seg = np.hypot(*np.diff(pts, axis=0).T) if len(pts) > 1 else np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(seg)])


def polyline_length(polyline: ArrayLike) -> float:
    return float(arc_lengths(polyline)[-1])


def drop_repeated_points(polyline: ArrayLike, tol_m: float = 1e-6) -> FloatArray:
    """Remove consecutive duplicates (SUMO shapes sometimes repeat a vertex)."""
    pts = as_points(polyline)
    if len(pts) < 2:
        return pts
    keep = np.concatenate([[True], np.hypot(*np.diff(pts, axis=0).T) > tol_m])
    return pts[keep]


def point_at(polyline: ArrayLike, s: float) -> FloatArray:
    """Point at arc length ``s`` along a polyline (clamped to its ends)."""
    pts = as_points(polyline)
    cum = arc_lengths(pts)
    s = min(max(s, 0.0), cum[-1])
    return np.array([np.interp(s, cum, pts[:, 0]), np.interp(s, cum, pts[:, 1])])


def resample(polyline: ArrayLike, max_spacing_m: float) -> FloatArray:
    """Resample a polyline with evenly spaced points no further apart than ``max_spacing_m``.

    Both end points are kept; interior vertices may be cut (corners are not preserved exactly),
    which is fine for the smooth lane centre lines and Bezier curves this is used on.
    """
    pts = drop_repeated_points(polyline)
    cum = arc_lengths(pts)
    total = cum[-1]
    if total == 0.0:
        return pts[:1].copy()
    n = max(1, math.ceil(total / max_spacing_m - 1e-9))
    s = np.linspace(0.0, total, n + 1)
    return np.column_stack([np.interp(s, cum, pts[:, 0]), np.interp(s, cum, pts[:, 1])])


def sub_polyline(polyline: ArrayLike, s_start: float, s_end: float) -> FloatArray:
    """The part of a polyline between arc lengths ``s_start`` and ``s_end`` (clamped)."""
    pts = drop_repeated_points(polyline)
    cum = arc_lengths(pts)
    s0, s1 = max(0.0, s_start), min(cum[-1], s_end)
    if s1 <= s0:
        p = point_at(pts, s0)
        return np.vstack([p, p])
    inner = pts[(cum > s0) & (cum < s1)]
    return np.vstack([point_at(pts, s0), inner, point_at(pts, s1)])


def placed_along(way: FloatArray, cum: FloatArray, front_m: FloatArray,
                 length: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Centres and headings [rad] of a car of ``length`` whose front is ``front_m`` along ``way``
    (arc lengths ``cum``), placed as SUMO places it: its front on the way, turned toward the point
    a length behind it on the way (before the way's start: on the line of its first segment)."""
    fx, fy = along_extended(way, cum, front_m)
    bx, by = along_extended(way, cum, front_m - length)
    headings = np.arctan2(fy - by, fx - bx)
    return fx - 0.5 * length * np.cos(headings), fy - 0.5 * length * np.sin(headings), headings


def along_extended(way: FloatArray, cum: FloatArray, s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The points ``s`` [m] along the polyline ``way`` (arc lengths ``cum``), as x and y arrays;
    before its start, on the line of its first segment (beyond its end: its end)."""
    x, y = np.interp(s, cum, way[:, 0]), np.interp(s, cum, way[:, 1])
    before = s < cum[0]
    if before.any():
        j = min(int(np.searchsorted(cum, cum[0], side="right")), len(cum) - 1)  # past repeated points
        span = float(cum[j] - cum[0])
        d = (way[j] - way[0]) / span if span > 0.0 else np.zeros(2)
        x = np.where(before, way[0, 0] + (s - cum[0]) * d[0], x)
        y = np.where(before, way[0, 1] + (s - cum[0]) * d[1], y)
    return x, y


def start_heading(polyline: ArrayLike) -> float:
    """Heading of the first segment of a polyline."""
    pts = drop_repeated_points(polyline)
    return heading_of(pts[1] - pts[0])


def end_heading(polyline: ArrayLike) -> float:
    """Heading of the last segment of a polyline."""
    pts = drop_repeated_points(polyline)
    return heading_of(pts[-1] - pts[-2])


def headings_and_curvatures(points: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Heading [rad] and signed curvature [1/m] at each vertex of a densely sampled polyline.

    Central differences inside, one-sided at the ends; heading is unwrapped before differencing so
    that curvature is continuous across ±π.
    """
    pts = as_points(points)
    if len(pts) < 2:
        return np.zeros(len(pts)), np.zeros(len(pts))
    s = arc_lengths(pts)
    dx = np.gradient(pts[:, 0], s, edge_order=1)
    dy = np.gradient(pts[:, 1], s, edge_order=1)
    heading = np.unwrap(np.arctan2(dy, dx))
    curvature = np.gradient(heading, s, edge_order=1) if len(pts) > 2 else np.zeros(len(pts))
    return wrap_angle(heading), curvature


# --- The paper's Bezier curve route (Sec. III-A) ----------------------------------------------


def bezier_control_points_closed_form(
    x1: ArrayLike, x4: ArrayLike, theta_in: float, theta_out: float, rho: float
) -> tuple[FloatArray, FloatArray]:
    """X2 and X3 by the paper's closed-form 2×2 matrices (eq. "feature points").

    ``theta_in`` is the heading of the entrance lane at X1, ``theta_out`` that of the exit lane
    at X4. This is the formula exactly as printed in the paper; the geometric construction it
    encodes is :func:`bezier_control_points_construction`.
    """
    p1, p4 = np.asarray(x1, float), np.asarray(x4, float)
    ci, si = math.cos(theta_in), math.sin(theta_in)
    co, so = math.cos(theta_out), math.sin(theta_out)
    a_in = np.array([[rho * ci**2 + si**2, (rho - 1) * si * ci],
                     [(rho - 1) * si * ci, ci**2 + rho * si**2]])
    b_in = (1 - rho) * np.array([[ci**2, si * ci], [si * ci, si**2]])
    a_out = (1 - rho) * np.array([[co**2, so * co], [so * co, so**2]])
    b_out = np.array([[rho * co**2 + so**2, (rho - 1) * so * co],
                      [(rho - 1) * so * co, co**2 + rho * so**2]])
    return a_in @ p1 + b_in @ p4, a_out @ p1 + b_out @ p4


def foot_of_perpendicular(point: ArrayLike, line_point: ArrayLike, line_heading: float) -> FloatArray:
    """Foot of the perpendicular from ``point`` onto the line through ``line_point`` at a heading."""
    d = unit(line_heading)
    p, q = np.asarray(point, float), np.asarray(line_point, float)
    return q + float(np.dot(p - q, d)) * d


def bezier_control_points_construction(
    x1: ArrayLike, x4: ArrayLike, theta_in: float, theta_out: float, rho: float
) -> tuple[FloatArray, FloatArray]:
    """X2 and X3 by the paper's geometric construction (independent of the closed form).

    The ρ-division points of X1–X4 are P2 = X1 + (1−ρ)(X4 − X1) and P3 = X4 + (1−ρ)(X1 − X4)
    (SPEC §1: the closed form is authoritative and places them there); X2 is the foot of the
    perpendicular from P2 onto the extended entrance line, X3 the foot from P3 onto the extended
    exit line.
    """
    p1, p4 = np.asarray(x1, float), np.asarray(x4, float)
    p2 = p1 + (1.0 - rho) * (p4 - p1)
    p3 = p4 + (1.0 - rho) * (p1 - p4)
    return foot_of_perpendicular(p2, p1, theta_in), foot_of_perpendicular(p3, p4, theta_out)


def cubic_bezier(control_points: ArrayLike, t: ArrayLike) -> FloatArray:
    """B(t) = X1(1−t)³ + 3X2 t(1−t)² + 3X3 t²(1−t) + X4 t³ for every t."""
    cp = as_points(control_points)
    if len(cp) != 4:
        raise ValueError("a cubic Bezier needs exactly 4 control points")
    tt = np.asarray(t, float)[:, None]
    u = 1.0 - tt
    return cp[0] * u**3 + 3 * cp[1] * tt * u**2 + 3 * cp[2] * tt**2 * u + cp[3] * tt**3


def sample_cubic_bezier(control_points: ArrayLike, max_spacing_m: float) -> FloatArray:
    """Points along a cubic Bezier spaced by at most ``max_spacing_m`` in arc length.

    The curve is first evaluated finely in t, then resampled by arc length, so spacing is even
    even where the parametrisation is not.
    """
    fine = cubic_bezier(control_points, np.linspace(0.0, 1.0, 2001))
    return resample(fine, max_spacing_m)


# --- Additions for the planner: Bezier derivatives, arc-length sampling in t, projection ----------


def cubic_bezier_derivatives(control_points: ArrayLike, t: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """First and second derivatives B'(t), B''(t) [m per unit t, m per unit t²] for every t."""
    cp = as_points(control_points)
    if len(cp) != 4:
        raise ValueError("a cubic Bezier needs exactly 4 control points")
    tt = np.asarray(t, float)[:, None]
    u = 1.0 - tt
    d1 = 3 * (cp[1] - cp[0]) * u**2 + 6 * (cp[2] - cp[1]) * tt * u + 3 * (cp[3] - cp[2]) * tt**2
    d2 = 6 * (cp[2] - 2 * cp[1] + cp[0]) * u + 6 * (cp[3] - 2 * cp[2] + cp[1]) * tt
    return d1, d2


def heading_curvature_from_derivatives(d1: ArrayLike, d2: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Heading [rad] and signed curvature [1/m] (positive turning left) of a parametric curve.

    κ = (x'y'' − y'x'') / |B'|³; ``d1``/``d2`` are ``(N, 2)`` first and second derivatives.
    """
    a, b = as_points(d1), as_points(d2)
    speed = np.hypot(a[:, 0], a[:, 1])
    if np.any(speed <= 1e-12):
        raise ValueError("the curve has a cusp (zero derivative): heading undefined")
    heading = np.arctan2(a[:, 1], a[:, 0])
    curvature = (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) / speed**3
    return heading, curvature


def sample_cubic_bezier_with_t(
    control_points: ArrayLike, max_spacing_m: float, n_fine: int = 4001
) -> tuple[FloatArray, FloatArray]:
    """Like :func:`sample_cubic_bezier`, also returning the parameter t of every sample.

    Samples are evenly spaced in arc length (spacing ≤ ``max_spacing_m``), measured on a fine
    polyline of ``n_fine`` points; the points are evaluated exactly on the curve at their t, so
    headings and curvatures can be taken analytically there.
    """
    cp = as_points(control_points)
    t_fine = np.linspace(0.0, 1.0, n_fine)
    cum = arc_lengths(cubic_bezier(cp, t_fine))
    total = cum[-1]
    if total == 0.0:
        raise ValueError("degenerate Bezier curve of zero length")
    # 0.1 % margin: t is interpolated linearly between fine samples, so a point may land a few
    # micrometres off its arc length; the margin keeps every gap within ``max_spacing_m``.
    n = max(1, math.ceil(total / (0.999 * max_spacing_m)))
    t = np.interp(np.linspace(0.0, total, n + 1), cum, t_fine)
    t[0], t[-1] = 0.0, 1.0
    return cubic_bezier(cp, t), t


def project_onto_polyline(polyline: ArrayLike, point: ArrayLike) -> tuple[int, float, float]:
    """Project a point onto a polyline: ``(segment index, arc length s [m], lateral offset [m])``.

    The nearest point of the polyline is found over all segments; ``s`` is its arc length from the
    first vertex, ``lateral`` the signed distance from the segment's line, positive to the left of
    the driving direction. Points beyond either end project onto the end point (s clamped) but keep
    their lateral offset from the extended end segment.
    """
    pts = as_points(polyline)
    p = np.asarray(point, float)
    if len(pts) < 2:
        raise ValueError("a polyline needs at least 2 points to project onto")
    a, b = pts[:-1], pts[1:]
    ab = b - a
    seg_len2 = np.einsum("ij,ij->i", ab, ab)
    seg_len2 = np.where(seg_len2 > 0.0, seg_len2, 1.0)
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / seg_len2, 0.0, 1.0)
    foot = a + t[:, None] * ab
    i = int(np.argmin(np.hypot(*(p - foot).T)))
    seg_len = math.sqrt(float(seg_len2[i]))
    cross = float(ab[i, 0] * (p[1] - a[i, 1]) - ab[i, 1] * (p[0] - a[i, 0]))
    s = float(arc_lengths(pts)[i] + t[i] * seg_len)
    return i, s, cross / seg_len


def distances_to_polyline(points: ArrayLike, polyline: ArrayLike) -> FloatArray:
    """The distance of each point to the nearest point of a polyline (its segments, not only its
    vertices) [m], as an ``(N,)`` array. A one-point polyline is treated as that point."""
    p = as_points(points)
    line = as_points(polyline)
    if len(line) == 0:
        raise ValueError("a polyline needs at least 1 point")
    if len(line) == 1:
        return np.hypot(*(p - line[0]).T)
    a, ab = line[:-1], np.diff(line, axis=0)
    seg_len2 = np.einsum("ij,ij->i", ab, ab)
    seg_len2 = np.where(seg_len2 > 0.0, seg_len2, 1.0)
    # (N, M) parameters of every point's foot on every segment, clamped onto the segment
    rel = p[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("nmk,mk->nm", rel, ab) / seg_len2, 0.0, 1.0)
    gap = rel - t[:, :, None] * ab[None, :, :]
    return np.sqrt(np.einsum("nmk,nmk->nm", gap, gap).min(axis=1))


def hausdorff_distance(a: ArrayLike, b: ArrayLike) -> float:
    """The largest distance from a vertex of either polyline to the other polyline [m]: how far
    apart two polylines drawn at ≤ some spacing run, to within that spacing's sagitta."""
    return float(max(distances_to_polyline(a, b).max(), distances_to_polyline(b, a).max()))


def polygons_of(geometry: object) -> list:
    """The shapely Polygons inside any geometry (Polygon, MultiPolygon, collections; else none)."""
    from shapely.geometry import MultiPolygon, Polygon

    if geometry is None or getattr(geometry, "is_empty", True):
        return []
    if isinstance(geometry, Polygon):
        return [geometry]
    if isinstance(geometry, MultiPolygon):
        return list(geometry.geoms)
    return [p for part in getattr(geometry, "geoms", []) for p in polygons_of(part)]


def footprint_points(xs: FloatArray, ys: FloatArray, headings: FloatArray, lengths: FloatArray,
                     widths: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(n, 9) x and y of points on each vehicle's footprint: its four corners, the middle of each
    side and its centre. A car crossing a corridor at least as wide as half a car is long has one
    of them inside it."""
    along = np.array([-1.0, -1.0, 1.0, 1.0, -1.0, 1.0, 0.0, 0.0, 0.0]) * 0.5
    across = np.array([-1.0, 1.0, -1.0, 1.0, 0.0, 0.0, -1.0, 1.0, 0.0]) * 0.5
    c, s = np.cos(headings)[:, None], np.sin(headings)[:, None]
    a, b = lengths[:, None] * along, widths[:, None] * across
    return xs[:, None] + a * c - b * s, ys[:, None] + a * s + b * c


def outside_box(px: FloatArray, py: FloatArray, cx: FloatArray | float, cy: FloatArray | float,
                heading: FloatArray | float, length: FloatArray | float, width: FloatArray | float) -> FloatArray:
    """How far [m] each point lies outside the box (centre, heading, length, width), by the larger
    of its distances beyond the box's ends and sides (negative inside); broadcasts."""
    c, s = np.cos(heading), np.sin(heading)
    dx, dy = px - cx, py - cy
    return np.maximum(np.abs(dx * c + dy * s) - 0.5 * np.asarray(length),
                      np.abs(dy * c - dx * s) - 0.5 * np.asarray(width))
