"""Safety and road constraints g(s) ≤ 0 and the exterior penalty φ (SPEC §4, paper Sec. IV-C).

Circles **(choice, documented)**: a body of length L and width W centred at (x, y) with heading φ is
represented by two circles of radius W/2 centred at ±(L − W)/2 along φ: they span the body's full
width and reach its front and rear ends on the axis (the corners stick out by at most
(√2 − 1)·W/2 ≈ 0.4 m for a car, which the safety margin covers). Circles sized to contain the whole
rectangle (radius √((L/4)² + (W/2)²) ≈ 1.56 m for a car) were rejected: two such cars in
neighbouring 3.5 m lanes would violate the constraint while simply driving side by side. The ego
(EGO_LENGTH_M × EGO_WIDTH_M) and vehicles and cyclists (their observed L, W) use two circles;
pedestrians one circle at the centre of radius r₁ = √((L/2)² + (W/2)²).

Safety: for every ego circle and every circle of every participant slot,
``g = r_ego + r_other + safety_margin_m − ‖c_ego − c_other‖`` (g ≤ 0 safe). Order along the last
axis: slot by slot (8 vehicles, 4 cyclists, 4 pedestrians as in the state), within a slot its
circles (rear, front), within a circle the ego circles (rear, front): 8·2·2 + 4·2·2 + 4·1·2 = 56.

Road **(choice)**: the intersection's road edges are not part of the state, so the road constraint
keeps each ego circle centre within ``lateral_bound_m`` of the reference path, measured
perpendicular to the reference heading through the reference point:
``g = ±(lateral offset) − lateral_bound_m`` → 4 values (rear +, rear −, front +, front −). The
default bound is a lane's half width less half the ego's width plus a little play
(see ROAD_LATERAL_BOUND_M).

Penalty, exactly as the paper: φ(g) = Σ min{0, −g}² — zero while g ≤ 0, (g)² once violated.
Numpy or torch, batched over leading dimensions, differentiable in torch.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from crossroads.arrays import ops
from crossroads.constants import EGO_LENGTH_M, EGO_WIDTH_M
from crossroads.idc.state import (
    DPHI,
    DY,
    KIND_OF_SLOT,
    O_L,
    O_PHI,
    O_PX,
    O_PY,
    O_W,
    PHI,
    PX,
    PY,
    others_block,
)

# [m] (choice) added to the sum of the radii. 1.0 m, not the 0.5 m used first: the circles leave a
# car's corners out by up to 0.41 m, perceived positions and lengths are noisy (σ 0.15 m and 0.3 m),
# and the exterior penalty lets a trained policy settle slightly inside the bound. With 0.5 m the
# first trained models crept into queued cars at 1-3 m/s with the model's g only 0.4-0.5 m violated
# (measured on the nominal left turn). Two cars in neighbouring 3.5 m lanes still do not bind
# (1 + 1 + 1.0 = 3.0 m < 3.5 m).
SAFETY_MARGIN_M = 1.0
EGO_CIRCLE_OFFSET_M = (EGO_LENGTH_M - EGO_WIDTH_M) / 2.0  # [m] circle centres at ± this along φ
EGO_RADIUS_M = EGO_WIDTH_M / 2.0  # [m]
LANE_WIDTH_M = 3.5  # [m] (choice) nominal lane width for the road constraint
ROAD_LATERAL_BOUND_M = LANE_WIDTH_M / 2.0  # [m] (choice) |lateral offset| of each ego circle centre
_EPS = 1e-12  # inside the square roots, so distances and radii are differentiable at 0

TWO_CIRCLE_SLOTS = tuple(i for i, k in enumerate(KIND_OF_SLOT) if k != "pedestrian")
ONE_CIRCLE_SLOTS = tuple(i for i, k in enumerate(KIND_OF_SLOT) if k == "pedestrian")
assert TWO_CIRCLE_SLOTS == tuple(range(len(TWO_CIRCLE_SLOTS))), "two-circle kinds come first"
# The participant slot each value of safety_constraints belongs to (its order: slot by slot, each
# slot's circles × the ego's 2 circles)
SAFETY_SLOT = tuple(slot for slot, k in enumerate(KIND_OF_SLOT) for _ in range(2 * (2 if k != "pedestrian" else 1)))
N_SAFETY = len(SAFETY_SLOT)  # 56
N_ROAD = 4


def ego_circles(state: Any) -> tuple[Any, Any, float]:
    """Centres of the ego's circles: x, y of shape [..., 2] (rear, front), and their radius."""
    xp = ops(state)
    px, py, phi = state[..., PX], state[..., PY], state[..., PHI]
    ox, oy = EGO_CIRCLE_OFFSET_M * xp.cos(phi), EGO_CIRCLE_OFFSET_M * xp.sin(phi)
    return xp.stack([px - ox, px + ox], axis=-1), xp.stack([py - oy, py + oy], axis=-1), EGO_RADIUS_M


def safety_constraints(state: Any, safety_margin_m: float = SAFETY_MARGIN_M) -> Any:
    """g[..., 56] between the ego's circles and every participant's circles (module docstring)."""
    xp = ops(state)
    state = xp.asarray(state, like=state)
    ex, ey, er = ego_circles(state)  # [..., 2]
    two_x, two_y, r2, one_x, one_y, r1 = participant_circles(others_block(state))

    def gap(cxs: Any, cys: Any, rs: Any) -> Any:
        """[..., slots, circles, 2 ego circles] → flattened [..., slots·circles·2]."""
        g = circle_gap(cxs[..., :, :, None], cys[..., :, :, None], rs[..., :, :, None],
                       ex[..., None, None, :], ey[..., None, None, :], er, safety_margin_m)
        return g.reshape(tuple(g.shape[:-3]) + (-1,))

    return xp.concat([gap(two_x, two_y, r2), gap(one_x, one_y, r1)], axis=-1)


def participant_circles(o: Any) -> tuple[Any, Any, Any, Any, Any, Any]:
    """The circles of the participants ``o`` [..., 16, 6] (module docstring): the two-circle slots'
    (the leading ones) centres x, y [..., n2, 2] (rear, front) and radius [..., n2, 1], then the
    one-circle slots' (the trailing ones) centre x, y [..., n1, 1] and radius [..., n1, 1]."""
    xp = ops(o)
    n2 = len(TWO_CIRCLE_SLOTS)
    two, one = o[..., :n2, :], o[..., n2:, :]
    ox, oy, length, width = two[..., O_PX], two[..., O_PY], two[..., O_L], two[..., O_W]
    off = xp.maximum(length - width, 0.0 * length) / 2.0
    cx, sx = off * xp.cos(two[..., O_PHI]), off * xp.sin(two[..., O_PHI])
    two_x = xp.stack([ox - cx, ox + cx], axis=-1)
    two_y = xp.stack([oy - sx, oy + sx], axis=-1)
    length, width = one[..., O_L], one[..., O_W]
    r1 = xp.sqrt(length * length / 4.0 + width * width / 4.0 + _EPS)
    return two_x, two_y, (two[..., O_W] / 2.0)[..., None], one[..., O_PX, None], one[..., O_PY, None], r1[..., None]


def circle_gap(cx: Any, cy: Any, r: Any, ex: Any, ey: Any, er: Any, safety_margin_m: float) -> Any:
    """g of circles at (cx, cy) of radius r against ego circles at (ex, ey) of radius er, broadcast:
    r + r_ego + margin − ‖c − c_ego‖ (the distance through √(· + ε), differentiable at 0)."""
    dx, dy = cx - ex, cy - ey
    return r + er + safety_margin_m - ops(dx).sqrt(dx * dx + dy * dy + _EPS)


_SLOT_STARTS = np.array([SAFETY_SLOT.index(slot) for slot in range(len(KIND_OF_SLOT))])


def deepest_by_slot(g: np.ndarray) -> np.ndarray:
    """g[..., 56] of :func:`safety_constraints` (numpy) → [..., 16]: each participant slot's largest
    value, so one participant's intrusion is not hidden behind another's."""
    return np.maximum.reduceat(np.asarray(g), _SLOT_STARTS, axis=-1)


def road_constraints(
    state: Any, ref_x: Any = None, ref_y: Any = None, ref_heading: Any = None,
    lateral_bound_m: float = ROAD_LATERAL_BOUND_M,
) -> Any:
    """g[..., 4]: lateral offset of each ego circle centre from the reference, against a bound.

    With ``ref_x, ref_y, ref_heading`` the offsets are measured from that reference point and
    heading; without them they come from the state's own x_track (Δy and Δφ): the circle centres
    lie at Δy ± (L/4)·sin Δφ from the reference line — the same numbers when x_track was built
    against that reference.
    """
    xp = ops(state, ref_x, ref_y, ref_heading)
    state = xp.asarray(state, like=state)
    if ref_x is None:
        dy, dphi = state[..., DY], state[..., DPHI]
        shift = EGO_CIRCLE_OFFSET_M * xp.sin(dphi)
        lat = xp.stack([dy - shift, dy + shift], axis=-1)
    else:
        rx, ry, rh = (xp.asarray(r, like=state) for r in (ref_x, ref_y, ref_heading))
        ex, ey, _ = ego_circles(state)
        c, s = xp.cos(rh)[..., None], xp.sin(rh)[..., None]
        lat = c * (ey - ry[..., None]) - s * (ex - rx[..., None])
    return xp.stack([lat[..., 0] - lateral_bound_m, -lat[..., 0] - lateral_bound_m,
                     lat[..., 1] - lateral_bound_m, -lat[..., 1] - lateral_bound_m], axis=-1)


def penalty(g: Any) -> Any:
    """φ = Σ over the last axis of min{0, −g}² (exterior point method): > 0 only where g > 0."""
    xp = ops(g)
    g = xp.asarray(g, like=g)
    m = xp.clip(-g, None, 0.0)
    return xp.sum(m * m, axis=-1)
