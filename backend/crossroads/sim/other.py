"""The surrounding participants' model f_other (SPEC §5, paper eq. "surr_model").

Row ``[p_x, p_y, v, φ, L, W]`` in the world frame::

    p_x' = p_x + Δt v cos φ + ξ_x        p_y' = p_y + Δt v sin φ + ξ_y
    v'   = v + ξ_v                       φ'   = φ + Δt v / R + ξ_φ
    L'   = L                             W'   = W

with 1/R the signed curvature κ of the participant's route at its position (0 on a straight
route, positive turning left), given per participant by :func:`route_curvature`. ξ comes from the
adversary (ranges ``constants.XI_RANGES``); ``None`` means ξ ≡ 0 (DPG and plain prediction).
The equation is applied exactly as printed (no clipping of v: the ξ ranges are the adversary's
business). Numpy or torch, batched over leading dimensions, differentiable in torch.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from crossroads.arrays import ops
from crossroads.constants import DT_S
from crossroads.geometry import FloatArray, arc_lengths, as_points, drop_repeated_points, wrap_angle

CURVATURE_WINDOW_M = 2.0  # [m] (choice) half-length of the route stretch the curvature is averaged over


def other_step(others: Any, curvature: Any, xi: Any | None = None, dt: float = DT_S) -> Any:
    """One step of f_other: ``others[..., 6]``, ``curvature[...]`` [1/m], ``xi[..., 4]`` → ``[..., 6]``.

    ``curvature`` broadcasts against ``others[..., 0]`` (a scalar 0 predicts straight motion for
    all); ``xi = [ξ_x, ξ_y, ξ_v, ξ_φ]`` broadcasts against ``others[..., :4]``.
    """
    xp = ops(others, curvature, xi)
    others = xp.asarray(others, like=others)
    kappa = xp.asarray(curvature, like=others)
    px, py, v, phi, length, width = (others[..., i] for i in range(6))
    px_n = px + dt * v * xp.cos(phi)
    py_n = py + dt * v * xp.sin(phi)
    v_n = v
    phi_n = phi + dt * v * kappa
    if xi is not None:
        xi = xp.asarray(xi, like=others)
        px_n, py_n = px_n + xi[..., 0], py_n + xi[..., 1]
        v_n, phi_n = v_n + xi[..., 2], phi_n + xi[..., 3]
    return xp.stack([px_n, py_n, v_n, phi_n, length, width], axis=-1)


def other_braking_step(others: Any, curvature: Any, decel_mps2: float, dt: float = DT_S) -> Any:
    """One step of f_other with every participant braking at ``decel_mps2`` until it stands: ξ_v =
    −min(v, decel·Δt), the rest of ξ zero (the "everyone brakes hard" future)."""
    xp = ops(others, curvature)
    others = xp.asarray(others, like=others)
    v = others[..., 2]
    dv = -xp.clip(v, 0.0, decel_mps2 * dt)
    zero = xp.zeros_like(v)
    return other_step(others, curvature, xp.stack([zero, zero, dv, zero], axis=-1), dt)


class RouteShape(NamedTuple):
    """A route polyline's distinct vertices (N, 2) [m] and the arc length at each [m]: what
    :func:`route_curvature` reads of it, computed once (:func:`route_shape`)."""

    points: FloatArray
    cum: FloatArray


def route_shape(points: ArrayLike) -> RouteShape:
    """:class:`RouteShape` of a polyline (consecutive repeated vertices dropped)."""
    pts = drop_repeated_points(as_points(points))
    return RouteShape(pts, arc_lengths(pts))


def route_curvature(points: ArrayLike | RouteShape, x: float, y: float,
                    window_m: float = CURVATURE_WINDOW_M) -> float:
    """Signed curvature [1/m] (positive turning left) of a route polyline near (x, y); ``points``
    may be its :class:`RouteShape`, computed once for a polyline looked at again and again.

    The vertex nearest to (x, y) is found; the heading change between the segment entering the
    stretch ``[s − window_m, s + window_m]`` around it and the segment leaving it, divided by the arc
    length between those two segments' midpoints, is the mean curvature there. Sparse SUMO shapes
    simply widen the stretch to the neighbouring vertices. Straight routes (fewer than 3 distinct
    vertices or no turn) give 0.
    """
    pts, cum = points if isinstance(points, RouteShape) else route_shape(points)
    n = len(pts)
    if n < 3:
        return 0.0
    i = int(np.argmin((pts[:, 0] - x) ** 2 + (pts[:, 1] - y) ** 2))
    lo = int(np.searchsorted(cum, cum[i] - window_m, side="right")) - 1
    hi = int(np.searchsorted(cum, cum[i] + window_m, side="left"))
    lo = min(max(lo, 0), max(i - 1, 0))
    hi = max(min(hi, n - 1), min(i + 1, n - 1))
    if hi - lo < 2:  # at an end of the route: use the two segments there
        lo = max(0, hi - 2)
        hi = min(n - 1, lo + 2)
    d_in, d_out = pts[lo + 1] - pts[lo], pts[hi] - pts[hi - 1]
    turn = float(wrap_angle(np.arctan2(d_out[1], d_out[0]) - np.arctan2(d_in[1], d_in[0])))
    span = 0.5 * (cum[hi] + cum[hi - 1]) - 0.5 * (cum[lo] + cum[lo + 1])
    return turn / span if span > 0.0 else 0.0
