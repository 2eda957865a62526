"""The 108-dimensional state s = [x_ego, x_track, x_other] (SPEC §4, paper Sec. IV-C), in one place.

Layout (indices into the last axis)::

    0:8     x_ego   = [p_x, p_y, v_x, v_y, φ, ω, δ, a]            world frame, as f_ego
    8:12    x_track = [Δx, Δy, Δv, Δφ]                            see tracking_error
    12:60   8 vehicles   × [p_x, p_y, v, φ, L, W]                  world frame, as f_other
    60:84   4 cyclists   × [p_x, p_y, v, φ, L, W]
    84:108  4 pedestrians × [p_x, p_y, v, φ, L, W]

Other participants are stored in the WORLD frame like the ego, so f_other and the safety
constraints apply to the state directly; :func:`network_input` makes everything relative for the
networks. In each kind's block the participants are sorted by distance to the ego, closest first;
empty slots hold virtual participants (:func:`pad_participant`).

x_track **(choice)**: the reference point is the nearest point of the candidate path (the foot of
the perpendicular on its nearest segment, heading and speed interpolated along that segment).
Δx and Δy are the ego's position error expressed in the reference's frame (longitudinal along
the path heading, lateral positive to the left), the paper's "longitudinal / lateral distance
error": Δx² + Δy² is the squared distance to the path whatever the frame, so the utility is
unchanged, while the errors do not depend on how the intersection is oriented. Δv = v_x − v_ref
(v_ref from the pass or stop speed profile, the only thing the speed mode changes, SPEC §7) and
Δφ = φ − φ_ref wrapped to ±π (``arrays.wrap_angle``; the numpy fast path of build_states wraps
into [-π, π), which differs only exactly at ±π).

The path preview **(choice, not the paper's; off unless asked for)**: states built with
``preview=True`` carry 12 more values after the 108, ``108:120``: for each of
``constants.PREVIEW_DISTANCES_M`` (5, 10, 15, 20 m of arc length beyond the reference point) the
path point's lateral offset in the ego's frame [m] (positive left), then for each the path's heading
there relative to the ego's [rad, wrapped], then for each the speed profile's v_ref there [m/s].
Why: x_track describes the nearest point only and :func:`network_input` drops the ego's absolute
pose, so a network fed the paper's 108 values cannot tell that the path bends or that the pass
profile drops at the stop line a few metres ahead (measured: docs/tried/training.md, "Seeing the
path ahead"). Networks built with ``path_preview`` read them; the model's cost never does, and networks
without it ignore them (they read the first 108), so a preview state serves both.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crossroads.arrays import NumpyOps, Ops, ops
from crossroads.constants import (
    ACCEL_MIN,
    EGO_LENGTH_M,
    EGO_STATE_DIM,
    EGO_WIDTH_M,
    LEAD_DIM,
    LEAD_LATERAL_MARGIN_M,
    LEAD_LOOKAHEAD_M,
    N_CYCLISTS_OBSERVED,
    N_PEDESTRIANS_OBSERVED,
    N_VEHICLES_OBSERVED,
    OTHER_STATE_DIM,
    PARTICIPANT_KINDS,
    PREVIEW_DIM,
    PREVIEW_DISTANCES_M,
    STATE_DIM,
    STEER_MAX,
    TRACK_STATE_DIM,
)
from crossroads.geometry import FloatArray, wrap_scalar
from crossroads.planning.routes import CandidatePath

# --- layout -----------------------------------------------------------------------------------------
EGO = slice(0, EGO_STATE_DIM)
TRACK = slice(EGO_STATE_DIM, EGO_STATE_DIM + TRACK_STATE_DIM)
OTHERS = slice(EGO_STATE_DIM + TRACK_STATE_DIM, STATE_DIM)
KINDS: tuple[str, ...] = PARTICIPANT_KINDS
SLOTS: dict[str, int] = {
    "vehicle": N_VEHICLES_OBSERVED, "cyclist": N_CYCLISTS_OBSERVED, "pedestrian": N_PEDESTRIANS_OBSERVED,
}
N_OTHERS = sum(SLOTS.values())  # 16
# rows of the (16, 6) block of each kind
KIND_ROWS: dict[str, slice] = {}
_row = 0
for _kind in KINDS:
    KIND_ROWS[_kind] = slice(_row, _row + SLOTS[_kind])
    _row += SLOTS[_kind]
del _row, _kind
# state indices of each kind's block
VEHICLES = slice(OTHERS.start, OTHERS.start + OTHER_STATE_DIM * SLOTS["vehicle"])
CYCLISTS = slice(VEHICLES.stop, VEHICLES.stop + OTHER_STATE_DIM * SLOTS["cyclist"])
PEDESTRIANS = slice(CYCLISTS.stop, STATE_DIM)
PREVIEW = slice(STATE_DIM, STATE_DIM + PREVIEW_DIM)  # the path preview of preview states
PREVIEW_STATE_DIM = STATE_DIM + PREVIEW_DIM  # 120
N_PREVIEW = len(PREVIEW_DISTANCES_M)
KIND_OF_SLOT: tuple[str, ...] = tuple(k for k in KINDS for _ in range(SLOTS[k]))  # 16 entries

# named indices
PX, PY, VX, VY, PHI, OMEGA, DELTA, ACC = range(EGO_STATE_DIM)
DX, DY, DV, DPHI = range(TRACK.start, TRACK.stop)
O_PX, O_PY, O_V, O_PHI, O_L, O_W = range(OTHER_STATE_DIM)

assert OTHERS.stop - OTHERS.start == OTHER_STATE_DIM * N_OTHERS == STATE_DIM - 12

# --- padding ------------------------------------------------------------------------------------------
PAD_DISTANCE_M = 100.0
"""[m] (choice) distance of the virtual participants that fill empty slots.

A pad stands PAD_DISTANCE_M behind the ego (opposite to its heading), heading the ego's way, speed 0,
with the ego's size (heading like the ego keeps its relative heading in the network input at 0,
away from the ±π discontinuity). No sensor sees that far (80 m at most), so a pad is never confused with a real
participant; and over a prediction horizon of T = 25 steps (2.5 s) it cannot come within any
safety threshold: the adversary's ξ moves it at most 25·0.8·√2 ≈ 28 m plus ≈ 7 m from the speed
ξ_v accumulates, the ego drives at most ≈ 40 m, and thresholds are a few metres — so its safety
constraints are far from binding and its penalty is exactly 0.
"""


def pad_participant(ego: ArrayLike) -> FloatArray:
    """The virtual participant ``[p_x − D cos φ, p_y − D sin φ, 0, φ, L_ego, W_ego]`` (D = PAD_DISTANCE_M)."""
    e = np.asarray(ego, dtype=np.float64)
    phi = float(e[PHI]) if e.shape[-1] > PHI else 0.0
    c, s = math.cos(phi), math.sin(phi)
    return np.array([e[PX] - PAD_DISTANCE_M * c, e[PY] - PAD_DISTANCE_M * s, 0.0, phi, EGO_LENGTH_M, EGO_WIDTH_M])


def select_others(
    ego_xy: ArrayLike, observations: ArrayLike, kinds: ArrayLike, ego_heading: float | None = None,
) -> FloatArray:
    """x_other as a (16, 6) block: the closest 8 vehicles, 4 cyclists, 4 pedestrians, padded.

    ``ego_xy`` is the ego's (x, y), or its whole state (8,) (then its heading places the pads);
    ``observations`` (n, 6) world-frame rows ``[p_x, p_y, v, φ, L, W]``, ``kinds`` (n,): the kind
    names, or their codes (integers: each kind's index in ``KINDS``, as ``Perceived.kind_codes``;
    faster, the same slots). Within each kind, rows are sorted by distance to the ego (closest first,
    ties keep the input order) and the empty slots are filled with :func:`pad_participant`. Names
    other than the three, and the code −1, are ignored.
    Which rows fill the slots: :func:`selected_rows`.
    """
    e = np.asarray(ego_xy, dtype=np.float64)
    obs = np.asarray(observations, dtype=np.float64).reshape(-1, OTHER_STATE_DIM)
    block = np.empty((N_OTHERS, OTHER_STATE_DIM))
    _fill_slots(block, obs, _slot_rows(e, obs, np.asarray(kinds)), float(e[0]), float(e[1]), _pad_heading(e, ego_heading))
    return block


def others_in_slots(ego_xy: ArrayLike, observations: ArrayLike, rows: NDArray[np.intp],
                    ego_heading: float | None = None) -> FloatArray:
    """The (16, 6) block of :func:`select_others` from its :func:`selected_rows` (for callers that
    need the rows too: the sort runs once). ``rows``: −1 (a pad) or a row of ``observations``."""
    e = np.asarray(ego_xy, dtype=np.float64)
    obs = np.asarray(observations, dtype=np.float64).reshape(-1, OTHER_STATE_DIM)
    block = np.empty((N_OTHERS, OTHER_STATE_DIM))
    _fill_slots(block, obs, np.asarray(rows).tolist(), float(e[0]), float(e[1]), _pad_heading(e, ego_heading))
    return block


def _pad_heading(ego: FloatArray, ego_heading: float | None) -> float:
    """The heading the pads take: ``ego_heading`` if given, else the ego state's (0 for an (x, y))."""
    return float(ego[PHI]) if (ego_heading is None and ego.shape[-1] > PHI) else float(ego_heading or 0.0)


def selected_rows(ego_xy: ArrayLike, observations: ArrayLike, kinds: ArrayLike) -> NDArray[np.intp]:
    """(16,) the row of ``observations`` in each slot of :func:`select_others`, −1 for a pad."""
    e = np.asarray(ego_xy, dtype=np.float64)
    obs = np.asarray(observations, dtype=np.float64).reshape(-1, OTHER_STATE_DIM)
    return np.array(_slot_rows(e, obs, np.asarray(kinds)), dtype=np.intp)


def _slot_rows(ego: FloatArray, obs: FloatArray, kinds: np.ndarray) -> list[int]:
    """:func:`selected_rows` as a list, of the float64 ego (its x, y first) and ``obs`` (n, 6)."""
    if len(obs) == 0:
        return list(_NO_ROWS)
    # the squared distances (x − x_e)² + (y − y_e)², squared in place (x·x: what ** 2 computes)
    d2 = obs[:, 0] - ego[0]
    dy = obs[:, 1] - ego[1]
    d2 *= d2
    dy *= dy
    d2 += dy
    # one stable sort of everyone, then each kind's first rows in that order: the same rows in the
    # same order as a stable sort within each kind (ties keep the input order either way), with
    # fewer numpy calls (this runs every control step on ~100 rows)
    order = d2.argsort(kind="stable")
    codes = (kinds if kinds.dtype.kind in "iu" else _kind_codes(kinds)).tolist()
    groups: tuple[list[int], ...] = ([], [], [], [])  # the three kinds', and (code −1) the ignored
    left = list(_SLOT_COUNTS_AND_NONE)  # free slots of each
    room = N_OTHERS
    for row in order.tolist():  # dealt out on Python ints, stopping when every slot is taken
        code = codes[row]
        if left[code]:
            left[code] -= 1
            groups[code].append(row)
            room -= 1
            if not room:
                break
    rows: list[int] = []
    for chosen, slots in zip(groups, _SLOT_COUNTS):
        rows += chosen
        rows += _PADS[slots - len(chosen)]
    return rows


def _kind_codes(names: np.ndarray) -> NDArray[np.int8]:
    """Each kind name's index in ``KINDS``; −1 (ignored) for any other name."""
    codes = np.full(len(names), -1, dtype=np.int8)
    for code, kind in enumerate(KINDS):
        codes[names == kind] = code
    return codes


def _fill_slots(block: FloatArray, obs: FloatArray, rows: list[int], x: float, y: float, heading: float) -> None:
    """Write the (16, 6) block of :func:`select_others` into ``block`` (a view may be given): the
    ``rows`` of ``obs`` (:func:`_slot_rows`), the pad of an ego at (x, y) with ``heading`` where a
    row is −1."""
    if len(obs):
        obs.take(rows, axis=0, out=block, mode="wrap")  # a pad's −1 takes the last row: overwritten below
    elif max(rows) >= 0:
        raise IndexError(f"rows {rows} of no observations")
    if len(obs) == 0 or -1 in rows:
        pad = _pad_row(x, y, heading)
        for slot, row in enumerate(rows):
            if row < 0:
                block[slot] = pad


_NO_ROWS = (-1,) * N_OTHERS  # every slot a pad
_SLOT_COUNTS = tuple(SLOTS[kind] for kind in KINDS)  # slots of each kind, in slot order
_SLOT_COUNTS_AND_NONE = (*_SLOT_COUNTS, 0)  # ... and none for an ignored kind (code −1, the last)
_PADS = tuple([-1] * k for k in range(max(SLOTS.values()) + 1))  # −1 k times: the pads after k rows


def _pad_row(x: float, y: float, heading: float) -> list[float]:
    """:func:`pad_participant` of an ego at (x, y) with ``heading``, on Python floats."""
    c, s = math.cos(heading), math.sin(heading)
    return [x - PAD_DISTANCE_M * c, y - PAD_DISTANCE_M * s, 0.0, heading, EGO_LENGTH_M, EGO_WIDTH_M]


def others_block(state: Any) -> Any:
    """View of x_other as ``[..., 16, 6]`` (numpy or torch)."""
    x = state[..., OTHERS]
    return x.reshape(tuple(x.shape[:-1]) + (N_OTHERS, OTHER_STATE_DIM))


# --- tracking error -----------------------------------------------------------------------------------


def tracking_error(ego: Any, ref_x: Any, ref_y: Any, ref_heading: Any, ref_v: Any) -> Any:
    """x_track = [Δx, Δy, Δv, Δφ] of ``ego[..., 8]`` against a reference point (module docstring).

    Δx, Δy: the position error p − p_ref in the reference frame (longitudinal, lateral-left);
    Δv = v_x − v_ref; Δφ = φ − φ_ref wrapped. Numpy or torch (differentiable in the ego state).
    """
    xp = ops(ego, ref_x, ref_y, ref_heading, ref_v)
    ego = xp.asarray(ego, like=ego)
    rx, ry, rh, rv = (xp.asarray(r, like=ego) for r in (ref_x, ref_y, ref_heading, ref_v))
    dx, dy = ego[..., PX] - rx, ego[..., PY] - ry
    c, s = xp.cos(rh), xp.sin(rh)
    return xp.stack([c * dx + s * dy, -s * dx + c * dy, ego[..., VX] - rv, xp.wrap(ego[..., PHI] - rh)], axis=-1)


class Reference(NamedTuple):
    """The reference point of a path for an ego position."""

    index: Any  # segment index i: the foot lies on points[i] → points[i + 1]
    x: Any  # [m]
    y: Any  # [m]
    heading: Any  # [rad]
    v: Any  # [m/s]
    s: Any = None  # arc length of the point [m] (reference_points_torch with arc lengths only)


HINT_BACK = 20  # (choice) points searched behind the hint (10 m at 0.5 m spacing)
HINT_AHEAD = 80  # (choice) points searched ahead of the hint (40 m)


def reference_point(
    path_points: ArrayLike, path_heading: ArrayLike, path_speed: ArrayLike, x: float, y: float,
    hint: int | None = None,
) -> Reference:
    """Nearest point of a path to (x, y): ``(index, ref_x, ref_y, ref_heading, ref_v)``.

    The foot of the perpendicular on the nearest segment (clamped to the segment), with heading
    and speed interpolated along it. With ``hint`` (the index of the previous step) only the
    segments from ``hint − 20`` to ``hint + 80`` are searched, unless the best one is at the edge of
    that window (then the whole path is searched).
    """
    pts = np.asarray(path_points, dtype=np.float64)
    head = np.asarray(path_heading, dtype=np.float64)
    speed = np.asarray(path_speed, dtype=np.float64)
    n = len(pts)
    if n == 1:
        return Reference(0, float(pts[0, 0]), float(pts[0, 1]), float(head[0]), float(speed[0]))
    lo, hi = 0, n - 1  # segment range [lo, hi)
    if hint is not None:
        lo, hi = max(0, int(hint) - HINT_BACK), min(n - 1, int(hint) + HINT_AHEAD)
        if hi <= lo:
            lo, hi = 0, n - 1
    while True:
        a, b = pts[lo:hi], pts[lo + 1: hi + 1]
        ab = b - a
        len2 = np.einsum("ij,ij->i", ab, ab)
        t = np.clip(((x - a[:, 0]) * ab[:, 0] + (y - a[:, 1]) * ab[:, 1]) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
        fx, fy = a[:, 0] + t * ab[:, 0], a[:, 1] + t * ab[:, 1]
        k = int(np.argmin((x - fx) ** 2 + (y - fy) ** 2))
        at_edge = (k == 0 and lo > 0) or (k == hi - lo - 1 and hi < n - 1)
        if not at_edge or (lo == 0 and hi == n - 1):
            break
        lo, hi = 0, n - 1
    i, w = lo + k, float(t[k])
    h = wrap_scalar(head[i] + w * wrap_scalar(head[i + 1] - head[i]))
    v = speed[i] + w * (speed[i + 1] - speed[i])
    return Reference(i, float(fx[k]), float(fy[k]), float(h), float(v))


# --- batched references in torch (training) --------------------------------------------------------


class PathTensors(NamedTuple):
    """P candidate paths as tensors, padded to a common length N by repeating the last point."""

    points: Any  # (P, N, 2)
    heading: Any  # (P, N)
    v_pass: Any  # (P, N)
    v_stop: Any  # (P, N)
    s: Any = None  # (P, N) arc length [m] (the path preview needs it)


def path_tensors(candidates: Sequence[CandidatePath], dtype: Any = None, device: Any = None) -> PathTensors:
    """Stack candidate paths into :class:`PathTensors` (torch; default dtype float32)."""
    import torch

    dtype = torch.float32 if dtype is None else dtype
    n = max(len(c.points) for c in candidates)

    def pad(a: np.ndarray) -> np.ndarray:
        return np.concatenate([a, np.repeat(a[-1:], n - len(a), axis=0)], axis=0)

    def t(arrs: list[np.ndarray]) -> Any:
        return torch.as_tensor(np.stack([pad(np.asarray(a, np.float64)) for a in arrs]), dtype=dtype, device=device)

    return PathTensors(t([c.points for c in candidates]), t([c.heading for c in candidates]),
                       t([c.v_pass for c in candidates]), t([c.v_stop for c in candidates]),
                       t([c.s for c in candidates]))


def reference_points_torch(
    paths: PathTensors, ego_xy: Any, path_index: Any = None, stop: Any = False,
) -> Reference:
    """Reference points for a batch of ego positions ``ego_xy`` (B, 2), in torch.

    Sample b uses path ``path_index[b]`` (a (B,) long tensor); with ``path_index=None`` one path
    (P = 1) serves all samples, or P = B pairs path b with sample b. ``stop`` (bool or (B,) bool
    tensor) picks the stop-mode speed profile instead of the pass one. Same geometry as
    :func:`reference_point` without a hint (all segments searched). The reference is data: it is
    computed without gradient (the index is not differentiable anyway); feed it to
    :func:`tracking_error` with the differentiable ego state.
    """
    import torch

    with torch.no_grad():
        xy = ego_xy.detach()
        b = xy.shape[0]
        p = paths.points.shape[0]
        if path_index is None:
            if p not in (1, b):
                raise ValueError(f"{p} paths for {b} samples: give path_index")
            path_index = torch.zeros(b, dtype=torch.long, device=xy.device) if p == 1 else torch.arange(b, device=xy.device)
        pts = paths.points.to(xy.dtype)[path_index]  # (B, N, 2)
        head = paths.heading.to(xy.dtype)[path_index]
        stop_t = torch.as_tensor(stop, device=xy.device, dtype=torch.bool).expand(b)
        speed = torch.where(stop_t[:, None], paths.v_stop.to(xy.dtype)[path_index], paths.v_pass.to(xy.dtype)[path_index])
        n = pts.shape[1]
        if n == 1:
            zero = torch.zeros(b, dtype=torch.long, device=xy.device)
            return Reference(zero, pts[:, 0, 0], pts[:, 0, 1], head[:, 0], speed[:, 0])
        a, ab = pts[:, :-1], pts[:, 1:] - pts[:, :-1]
        len2 = (ab * ab).sum(-1)
        rel = xy[:, None, :] - a
        t = torch.clamp((rel * ab).sum(-1) / torch.where(len2 > 0, len2, torch.ones_like(len2)), 0.0, 1.0)
        foot = a + t[..., None] * ab
        i = torch.argmin(((xy[:, None, :] - foot) ** 2).sum(-1), dim=1)  # (B,)
        rows = torch.arange(b, device=xy.device)
        w = t[rows, i]
        h0, h1 = head[rows, i], head[rows, i + 1]
        dh = torch.remainder(h1 - h0 + math.pi, 2.0 * math.pi) - math.pi
        h = torch.remainder(h0 + w * dh + math.pi, 2.0 * math.pi) - math.pi
        v = speed[rows, i] + w * (speed[rows, i + 1] - speed[rows, i])
        s = None
        if paths.s is not None:
            arc = paths.s.to(xy.dtype)[path_index]
            s = arc[rows, i] + w * (arc[rows, i + 1] - arc[rows, i])
        return Reference(i, foot[rows, i, 0], foot[rows, i, 1], h, v, s)


def preview_features(ego: Any, ahead_x: Any, ahead_y: Any, ahead_heading: Any, ahead_v: Any) -> Any:
    """The path preview ``[..., 12]`` of ``ego[..., 8]`` from the path's points ahead (each ``[..., 4]``):
    their lateral offsets in the ego frame, their headings relative to the ego's (wrapped), their
    v_ref (module docstring). Numpy or torch (differentiable in the ego's pose)."""
    xp = ops(ego, ahead_x)
    px, py, phi = ego[..., PX][..., None], ego[..., PY][..., None], ego[..., PHI][..., None]
    lateral = -xp.sin(phi) * (ahead_x - px) + xp.cos(phi) * (ahead_y - py)
    return xp.concat([lateral, xp.wrap(ahead_heading - phi), ahead_v], axis=-1)


def preview_torch(paths: PathTensors, ego: Any, ref: Reference, path_index: Any, stop: Any) -> Any:
    """The path preview ``[B, 12]`` of a batch (torch): the points ``PREVIEW_DISTANCES_M`` beyond each
    reference point ``ref`` (from :func:`reference_points_torch`) along path ``path_index[b]``,
    clamped to the path's end. The points are data (no gradient); the features are differentiable
    in the ego's pose."""
    import torch

    if paths.s is None or ref.s is None:
        raise ValueError("the path preview needs the paths' arc lengths (PathTensors.s): build them with path_tensors")
    with torch.no_grad():
        dtype = ref.x.dtype
        arc = paths.s.to(dtype)[path_index]  # (B, N)
        n = arc.shape[1]
        distances = torch.as_tensor(PREVIEW_DISTANCES_M, dtype=dtype, device=arc.device)
        target = torch.minimum(ref.s[:, None] + distances, arc[:, -1:])  # (B, K)
        j = (torch.searchsorted(arc.contiguous(), target.contiguous(), right=True) - 1).clamp(0, max(n - 2, 0))
        j1 = (j + 1).clamp(max=n - 1)
        s0, s1 = arc.gather(1, j), arc.gather(1, j1)
        w = torch.where(s1 > s0, (target - s0) / torch.where(s1 > s0, s1 - s0, torch.ones_like(s0)),
                        torch.zeros_like(s0)).clamp(0.0, 1.0)
        pts = paths.points.to(dtype)[path_index]  # (B, N, 2)
        x = pts[..., 0].gather(1, j) + w * (pts[..., 0].gather(1, j1) - pts[..., 0].gather(1, j))
        y = pts[..., 1].gather(1, j) + w * (pts[..., 1].gather(1, j1) - pts[..., 1].gather(1, j))
        head = paths.heading.to(dtype)[path_index]
        h0 = head.gather(1, j)
        dh = torch.remainder(head.gather(1, j1) - h0 + math.pi, 2.0 * math.pi) - math.pi
        h = torch.remainder(h0 + w * dh + math.pi, 2.0 * math.pi) - math.pi
        stop_t = torch.as_tensor(stop, device=arc.device, dtype=torch.bool).expand(arc.shape[0])
        speed = torch.where(stop_t[:, None], paths.v_stop.to(dtype)[path_index], paths.v_pass.to(dtype)[path_index])
        v = speed.gather(1, j) + w * (speed.gather(1, j1) - speed.gather(1, j))
    return preview_features(ego, x, y, h, v)


# --- building states for every candidate (online, numpy) ----------------------------------------------


class _Stacked(NamedTuple):
    candidates: tuple[CandidatePath, ...]
    ax: np.ndarray  # (C, M) segment starts (padding: the last point)
    ay: np.ndarray
    abx: np.ndarray  # (C, M) segment vectors (0 on padding)
    aby: np.ndarray
    inv_len2: np.ndarray  # (C, M) 1/|ab|² (0 on padding → t = 0)
    pack: dict[str, np.ndarray]  # mode → (C·M, 8): ax, ay, abx, aby, h0, dh, v0, dv per segment
    s0: np.ndarray  # (C, M) arc length at each segment's start (the path preview)
    ds: np.ndarray  # (C, M) each segment's length in arc length
    ahead: tuple[dict[str, np.ndarray], ...]  # per candidate: s, x, y, unwrapped heading, pass, stop
    row_starts: np.ndarray  # (C,) c·M: where candidate c's segments start in the flattened (C, M)
    scale: float  # [m] the largest |coordinate| of the paths' points, and more (the rounding's scale)
    # mode → the rows of pack[mode] as Python floats, "preview " + mode → the points of the path
    # preview (_preview_points), made when first asked
    segments: dict[str, Any]
    shared: int  # the first segments every candidate has alike (start, vector, heading): their common stretch


_CACHE: dict[tuple[int, ...], _Stacked] = {}
_CACHE_SIZE = 64
# (candidates, their stacks) of the last call with a tuple: the online loop passes the same tuple
# every step, and one identity check replaces building the key (only tuples: a list may change in
# place; holding the tuple keeps its id from being reused)
_LAST: list[tuple[tuple[CandidatePath, ...], _Stacked] | None] = [None]


def _stacked(candidates: Sequence[CandidatePath]) -> _Stacked:
    last = _LAST[0]
    if last is not None and last[0] is candidates:  # the same tuple as last time (the online loop)
        return last[1]
    stacked = _stacked_of(candidates)
    if isinstance(candidates, tuple):
        _LAST[0] = (candidates, stacked)
    return stacked


def _stacked_of(candidates: Sequence[CandidatePath]) -> _Stacked:
    key = tuple(id(c) for c in candidates)
    hit = _CACHE.get(key)
    if hit is not None and all(a is b for a, b in zip(hit.candidates, candidates)):
        return hit
    m = max(max(len(c.points) - 1, 1) for c in candidates)

    def seg(a: np.ndarray, start: bool) -> np.ndarray:
        """Per-segment start values (or changes along it) of a per-point array, padded to m."""
        a = np.asarray(a, np.float64)
        if len(a) == 1:
            a = np.concatenate([a, a])
        s = a[:-1] if start else a[1:] - a[:-1]
        fill = a[-1] if start else np.zeros_like(a[-1])
        return np.concatenate([s, np.repeat(fill[None], m - len(s), axis=0)]) if len(s) < m else s

    pts = np.stack([seg(c.points, True) for c in candidates])  # (C, M, 2)
    ab = np.stack([seg(c.points, False) for c in candidates])
    len2 = (ab**2).sum(-1)
    head = [np.asarray(c.heading, np.float64) for c in candidates]
    h0 = np.stack([seg(h, True) for h in head])
    dh = np.stack([np.mod(seg(h, False) + math.pi, 2.0 * math.pi) - math.pi for h in head])
    pack = {}
    for mode in ("pass", "stop"):
        v = [np.asarray(c.v_pass if mode == "pass" else c.v_stop, np.float64) for c in candidates]
        v0, dv = np.stack([seg(a, True) for a in v]), np.stack([seg(a, False) for a in v])
        pack[mode] = np.stack([pts[..., 0], pts[..., 1], ab[..., 0], ab[..., 1], h0, dh, v0, dv],
                              axis=-1).reshape(-1, 8)
    arcs = [np.asarray(c.s, np.float64) for c in candidates]
    ahead = tuple({"s": np.asarray(c.s, np.float64), "x": np.asarray(c.points, np.float64)[:, 0],
                   "y": np.asarray(c.points, np.float64)[:, 1], "heading": np.unwrap(h),
                   "pass": np.asarray(c.v_pass, np.float64), "stop": np.asarray(c.v_stop, np.float64)}
                  for c, h in zip(candidates, head))
    stacked = _Stacked(
        tuple(candidates), pts[..., 0].copy(), pts[..., 1].copy(), ab[..., 0].copy(), ab[..., 1].copy(),
        np.where(len2 > 0, 1.0 / np.where(len2 > 0, len2, 1.0), 0.0), pack,
        np.stack([seg(a, True) for a in arcs]), np.stack([seg(a, False) for a in arcs]), ahead,
        np.arange(len(candidates)) * m, float(np.abs(pts).max() + np.abs(ab).max()), {},
        _common_prefix(np.stack([pts[..., 0], pts[..., 1], ab[..., 0], ab[..., 1], h0, dh], axis=-1)),
    )
    if len(_CACHE) >= _CACHE_SIZE:
        _CACHE.pop(next(iter(_CACHE)))
    _CACHE[key] = stacked
    return stacked


def _common_prefix(rows: FloatArray) -> int:
    """How many leading rows of ``rows`` (C, M, k) are the same floats for every candidate."""
    alike = (rows == rows[:1]).all(axis=(0, 2))
    return int(alike.argmin()) if not alike.all() else len(alike)


def _slack(st: _Stacked, x: float, y: float) -> float:
    """[m] more than a computed distance between (x, y) and a segment, or the √(Δx² + Δy²) of
    x_track, can be off the true distance (their rounding: ~1e-16 of the coordinates involved),
    by far: what :func:`_certain_nearest` keeps clear of."""
    return 1e-6 + 1e-9 * (abs(x) + abs(y) + st.scale)


# (stacks, x, y, their _nearest) of the last search: an ego standing still asks again for the same
# point every step (waiting at a light or in a queue: half the steps of a nominal left turn), and
# the answer of a pure function of the same floats is the same
_LAST_NEAREST: list[tuple[_Stacked, float, float, tuple[list[int], list[float], list[float]]] | None] = [None]


def _nearest(st: _Stacked, x: float, y: float) -> tuple[list[int], list[float], list[float]]:
    """(i, w, d), one of each per candidate: its segment nearest to (x, y) (the first of equals),
    the position w ∈ [0, 1] of the foot of (x, y) along it and the squared distance from (x, y) to
    that foot, as computed. Fresh lists every call (callers may keep them)."""
    last = _LAST_NEAREST[0]
    if last is not None and last[0] is st and last[1] == x and last[2] == y:
        i, w, d = last[3]
        return i[:], w[:], d[:]
    found = _search_segments(st, x, y)
    _LAST_NEAREST[0] = (st, x, y, (found[0][:], found[1][:], found[2][:]))
    return found


def _search_segments(st: _Stacked, x: float, y: float) -> tuple[list[int], list[float], list[float]]:
    """:func:`_nearest`, computed: every segment of every candidate at once."""
    relx, rely = x - st.ax, y - st.ay
    t = (relx * st.abx + rely * st.aby) * st.inv_len2
    np.maximum(t, 0.0, out=t)
    np.minimum(t, 1.0, out=t)
    relx -= t * st.abx
    rely -= t * st.aby
    relx *= relx
    rely *= rely
    relx += rely
    i = relx.argmin(axis=1)
    flat = i + st.row_starts
    return i.tolist(), t.take(flat).tolist(), relx.take(flat).tolist()


def _check_mode(mode: str) -> None:
    if mode not in ("pass", "stop"):
        raise ValueError(f"unknown speed mode {mode!r}; expected 'pass' or 'stop'")


def references(candidates: Sequence[CandidatePath], x: float, y: float, mode: str = "pass") -> Reference:
    """Reference point of every candidate at once: each field an array of shape (n_candidates,).

    Same geometry as :func:`reference_point` without a hint (all segments searched).
    """
    _check_mode(mode)
    st = _stacked(candidates)
    i, fractions, _ = _nearest(st, x, y)
    w = np.array(fractions)
    index = np.array(i)
    ax, ay, abx, aby, h0, dh, v0, dv = st.pack[mode][index + st.row_starts].T
    h = np.mod(h0 + w * dh + math.pi, 2.0 * math.pi) - math.pi
    return Reference(index, ax + w * abx, ay + w * aby, h, v0 + w * dv)


def build_states(
    ego: ArrayLike, others16: ArrayLike, candidates: Sequence[CandidatePath], mode: str,
    preview: bool = False,
) -> FloatArray:
    """One state per candidate path, ``(n_candidates, 108)``: shared x_ego and x_other, own x_track;
    with ``preview``, ``(n_candidates, 120)``: each followed by its path preview (module docstring).

    ``mode`` ("pass" | "stop") picks the speed profile of Δv. Vectorised over the candidates' points
    (their segment arrays are stacked once and cached per tuple of candidates).
    """
    _check_mode(mode)
    e = np.asarray(ego, dtype=np.float64)
    st = _stacked(candidates)
    px, py, vx, _, phi = e[:PHI + 1].tolist()
    i, w, _ = _nearest(st, px, py)
    out = np.empty((len(w), PREVIEW_STATE_DIM if preview else STATE_DIM))
    out[:, EGO] = e
    out[:, OTHERS] = np.asarray(others16, dtype=np.float64).reshape(-1)
    out[:, TRACK] = _tracks(st, i, w, mode, px, py, vx, phi)
    if preview:
        out[:, PREVIEW] = _preview(st, e, i, w, mode)
    return out


def tracked_state(
    ego: ArrayLike, observations: ArrayLike, kinds: ArrayLike, candidates: Sequence[CandidatePath],
    mode: str, path: int | None = None, preview: bool = False,
) -> tuple[int, FloatArray]:
    """(the tracked candidate, its state): the row ``path`` of ``build_states(ego,
    select_others(ego, observations, kinds), candidates, mode, preview)``, the same numbers, built
    alone. ``path=None`` tracks the candidate nearest the ego: least √(Δx² + Δy²), the first of
    equals, ``np.hypot(states[:, DX], states[:, DY]).argmin()`` of those states.

    For a caller that needs one state a step (the Gymnasium environment): x_track is computed for
    the tracked candidate only when the segment search tells the nearest for certain
    (:func:`_certain_nearest`), the others are written straight into the state, and no state of
    the other candidates is assembled.
    """
    _check_mode(mode)
    e = np.asarray(ego, dtype=np.float64)
    obs = np.asarray(observations, dtype=np.float64).reshape(-1, OTHER_STATE_DIM)
    st = _stacked(candidates)
    px, py, vx, _, phi = e[:PHI + 1].tolist()
    i, w, d = _nearest(st, px, py)
    if path is not None:
        index = range(len(w))[path]
    elif i[0] < st.shared and i.count(i[0]) == len(i) and w.count(w[0]) == len(w):
        # every foot at one place on the stretch the candidates share (the ego before the junction,
        # where they split): the same Δx, Δy for all, so the first is the least (the argmin below)
        index = 0
    else:
        index = _certain_nearest(d, _slack(st, px, py))
        if index is None:  # a tie or a near one: numpy's hypot of every candidate's x_track decides
            tracks = _tracks(st, i, w, mode, px, py, vx, phi)
            index = int(np.hypot([t[0] for t in tracks], [t[1] for t in tracks]).argmin())
    segment = _segments(st, mode)[i[index] + index * st.ax.shape[1]]
    out = np.empty(PREVIEW_STATE_DIM if preview else STATE_DIM)
    out[EGO] = e
    out[TRACK] = _track(px, py, vx, phi, w[index], *segment)
    _fill_slots(out[OTHERS].reshape(N_OTHERS, OTHER_STATE_DIM), obs, _slot_rows(e, obs, np.asarray(kinds)),
                px, py, phi)
    if preview:  # every candidate's, as build_states computes them, and the tracked one's kept
        out[PREVIEW] = _preview(st, e, i, w, mode)[index]
    return index, out


def _certain_nearest(d: list[float], slack: float) -> int | None:
    """The candidate of least √(Δx² + Δy²) from the squared distances ``d`` of the segment search
    (:func:`_nearest`), when they tell it for certain: both measure the distance from the ego to
    the same foot and differ by rounding only (< ``slack``), so a candidate nearer than every other
    by more than twice that is the nearest by either. None otherwise (ties, near ties, NaN)."""
    if len(d) == 1:
        return 0
    ranked = sorted(d)
    least = ranked[0]
    if math.isfinite(sum(d)) and math.sqrt(ranked[1]) > math.sqrt(least) + 2.0 * slack:
        return d.index(least)
    return None


def _tracks(st: _Stacked, i: list[int], w: list[float], mode: str, px: float, py: float, vx: float,
            phi: float) -> list[list[float]]:
    """x_track of each candidate against the foot a fraction ``w[c]`` along its segment ``i[c]``."""
    # on Python floats: the arithmetic of references() and tracking_error element by element (same
    # numbers; math.cos/sin give numpy's float64 cos/sin, tests/idc/test_state.py), without ~40
    # numpy calls on arrays of 3
    segments, m = _segments(st, mode), st.ax.shape[1]
    return [_track(px, py, vx, phi, fraction, *segments[k + c * m]) for c, (k, fraction) in enumerate(zip(i, w))]


def _segments(st: _Stacked, mode: str) -> list[list[float]]:
    """The rows of ``st.pack[mode]`` (one per segment) as Python floats: a segment's row without a
    numpy call."""
    rows = st.segments.get(mode)
    if rows is None:
        rows = st.segments[mode] = st.pack[mode].tolist()
    return rows


def _preview(st: _Stacked, ego: FloatArray, i: list[int], w: list[float], mode: str) -> FloatArray:
    """The path preview ``(C, 12)`` of every candidate, the foot of candidate c a fraction ``w[c]``
    along its segment ``i[c]`` (the numbers of :func:`preview_torch`, up to rounding).

    On Python floats: ``np.interp`` of each path's values at the distances ahead and
    :func:`preview_features`, term by term, the same arithmetic in the same order, so the same
    numbers (tests/idc/test_state.py) without some thirty numpy calls on arrays of a few values
    (most of :func:`build_states`' time with them: benchmarks/decision_latency.py)."""
    px, py, phi = float(ego[PX]), float(ego[PY]), float(ego[PHI])
    sin_phi, cos_phi = math.sin(phi), math.cos(phi)  # numpy's float64 sin and cos (as in _track)
    rows = []
    for k, fraction, (s, columns, s0, ds) in zip(i, w, _preview_points(st, mode)):
        arc = s0[k] + fraction * ds[k]
        ahead = [_interp_at(min(arc + distance, s[-1]), s, columns) for distance in PREVIEW_DISTANCES_M]
        lateral, heading, speed = [], [], []
        for x, y, h, v in ahead:
            h = (h + math.pi) % (2.0 * math.pi) - math.pi  # the path's heading, wrapped
            lateral.append(-sin_phi * (x - px) + cos_phi * (y - py))
            heading.append((h - phi + math.pi) % (2.0 * math.pi) - math.pi)
            speed.append(v)
        rows.append(lateral + heading + speed)
    return np.array(rows, dtype=np.float64).reshape(len(rows), PREVIEW_DIM)


PreviewPoints = tuple[list[float], tuple[list[float], ...], list[float], list[float]]


def _preview_points(st: _Stacked, mode: str) -> list[PreviewPoints]:
    """Per candidate, as Python floats: its points' arc lengths; their x, y, unwrapped heading and
    v_ref of ``mode``; its segments' arc lengths at their start and along them (``st.s0``,
    ``st.ds``). Made when first asked, then kept in ``st.segments``."""
    key = "preview " + mode
    points = st.segments.get(key)
    if points is None:
        points = st.segments[key] = [
            (path["s"].tolist(), tuple(path[k].tolist() for k in ("x", "y", "heading", mode)), s0, ds)
            for path, s0, ds in zip(st.ahead, st.s0.tolist(), st.ds.tolist())]
    return points


def _interp_at(t: float, s: list[float], columns: tuple[list[float], ...]) -> list[float]:
    """``np.interp(t, s, column)`` of each column, on Python floats: its arithmetic (slope of the
    segment times the distance into it, plus its start) and its special cases (a NaN, before the
    first point, at a point or past the last)."""
    if t != t:
        return [t] * len(columns)
    j = bisect.bisect_right(s, t) - 1  # s[j] ≤ t < s[j + 1]
    if j < 0:
        return [column[0] for column in columns]
    if j >= len(s) - 1 or s[j] == t:
        return [column[j] for column in columns]
    s_j, s_next = s[j], s[j + 1]
    out = []
    for column in columns:
        y_j, y_next = column[j], column[j + 1]
        slope = (y_next - y_j) / (s_next - s_j)
        value = slope * (t - s_j) + y_j
        if value != value:  # np.interp tries from the other end, then a flat segment's value
            value = slope * (t - s_next) + y_next
            if value != value and y_j == y_next:
                value = y_j
        out.append(value)
    return out


def _track(px: float, py: float, vx: float, phi: float, w: float, ax: float, ay: float, abx: float,
           aby: float, h0: float, dh: float, v0: float, dv: float) -> list[float]:
    """x_track against the point a fraction ``w`` along one reference segment (its pack row)."""
    heading = (h0 + w * dh + math.pi) % (2.0 * math.pi) - math.pi
    dx, dy = px - (ax + w * abx), py - (ay + w * aby)
    c, s = math.cos(heading), math.sin(heading)
    return [c * dx + s * dy, c * dy - s * dx, vx - (v0 + w * dv),
            (phi - heading + math.pi) % (2.0 * math.pi) - math.pi]


# --- network input ---------------------------------------------------------------------------------

POSITION_SCALE_M = 20.0  # (choice) others' relative position [m] per unit
SPEED_SCALE_MPS = 10.0  # (choice) speeds and Δv [m/s] per unit
YAW_RATE_SCALE = 1.0  # (choice) ω [rad/s] per unit
SIZE_SCALE_M = 5.0  # (choice) L, W [m] per unit
TRACK_POSITION_SCALE_M = 2.0  # (choice) Δx, Δy [m] per unit
ANGLE_SCALE = math.pi  # relative headings and Δφ [rad] per unit (wrapped angles → [-1, 1))


PREVIEW_LATERAL_SCALE_M = 5.0  # (choice) the preview's lateral offsets [m] per unit


def lead_features(states: Any) -> Any:
    """The lead summary ``[..., 3]`` of states ``[..., 108+]`` (numpy/torch; **choice, not the paper's**):
    of the participants whose centre lies ahead of the ego and within half their width + half the
    ego's + 0.3 m of its heading line, the nearest by bumper gap (its centre distance − half its length
    − half the ego's, at least 0), up to 40 m; as [gap / 40 m, (v_x − its speed along the ego's
    heading) / 10 m/s, 1]. An empty corridor reads [1, 0, 0].

    Why: the 16 participant slots are sorted by distance, so the car the ego queues behind sits in
    whichever slot its distance gives it among the oncoming cars, cyclists and pedestrians around;
    measured (an APG trained with the stopping tail and the mean loss), 2 s before 31 collisions with a vehicle ahead
    the policy's plan met that vehicle in 3 with the other slots padded and in 17 with the scene as seen.
    A straight corridor, not the path: it is the ego's own heading that carries it into what is ahead
    within a few seconds. Differentiable in the positions (the gap) through the chosen participant.
    """
    xp = ops(states)
    states = xp.asarray(states, like=states)
    o = others_block(states)
    return _lead(xp, states, o, *_ego_frame(xp, states, o))


def _ego_frame(xp: Any, states: Any, o: Any) -> tuple[Any, Any]:
    """(ahead, lateral) ``[..., 16]``: each participant of ``o = others_block(states)`` relative to
    the ego, rotated into its frame (x forward, y left) [m]."""
    phi = states[..., PHI]
    c, s = xp.cos(phi)[..., None], xp.sin(phi)[..., None]
    dx, dy = o[..., O_PX] - states[..., PX][..., None], o[..., O_PY] - states[..., PY][..., None]
    return c * dx + s * dy, c * dy - s * dx


def _lead(xp: Any, states: Any, o: Any, ahead: Any, lateral: Any) -> Any:
    """:func:`lead_features` from the participants already in the ego's frame (:func:`_ego_frame`)."""
    phi, vx = states[..., PHI], states[..., VX]
    reach = 0.5 * (o[..., O_W] + EGO_WIDTH_M) + LEAD_LATERAL_MARGIN_M
    inside = (ahead > 0.0) & (xp.abs(lateral) < reach)
    gap = xp.clip(ahead - 0.5 * (o[..., O_L] + EGO_LENGTH_M), 0.0, LEAD_LOOKAHEAD_M)
    gap = xp.where(inside, gap, LEAD_LOOKAHEAD_M)
    nearest = xp.argmin(gap, axis=-1)[..., None]
    lead_gap = xp.take_along(gap, nearest, axis=-1)[..., 0]
    along = o[..., O_V] * xp.cos(o[..., O_PHI] - phi[..., None])
    lead_v = xp.take_along(along, nearest, axis=-1)[..., 0]
    present = xp.take_along(xp.asarray(inside, like=gap), nearest, axis=-1)[..., 0]
    return xp.stack([lead_gap / LEAD_LOOKAHEAD_M, present * (vx - lead_v) / SPEED_SCALE_MPS, present], axis=-1)


def network_input(states: Any, preview: bool = False, lead: bool = False, xp: Ops | None = None) -> Any:
    """Normalised, pose-invariant network input ``[..., 108]`` from states ``[..., 108]`` (numpy/torch);
    with ``preview``, ``[..., 120]`` from preview states ``[..., 120]`` (module docstring), the preview
    as lateral offsets / 5 m, relative headings / π and v_ref / 10 m/s. Without it a preview state's
    last 12 values are ignored. With ``lead`` the 3 values of :func:`lead_features` follow (computed
    from the state: nothing more is stored).

    **(choice)** Everything is expressed relative to the ego so one policy fits every intersection
    and approach: the ego's absolute position and heading are replaced by 0 (slots 0, 1, 4 kept
    so the layout is the same); v_x, v_y are divided by 10 m/s, ω by 1 rad/s, δ by δ_max, a by
    |a_min|; x_track is already path-relative (Δx, Δy / 2 m, Δv / 10 m/s, Δφ / π). Each other
    participant becomes [x, y] = its position relative to the ego rotated into the ego frame
    (x forward, y left) / 20 m, v / 10 m/s, its heading relative to the ego's wrapped / π, L and
    W / 5 m. Pads (100 m behind) thus sit at (−5, 0), speed 0, relative heading 0.

    ``xp``: the array namespace (default: :func:`crossroads.arrays.ops` of ``states``); the online
    decision passes :class:`crossroads.arrays.TorchTrigNumpyOps` with float32 states, which gives
    the torch path's numbers bit for bit at a fraction of its cost.
    """
    xp = ops(states) if xp is None else xp
    states = xp.asarray(states, like=states)
    if preview and states.shape[-1] != PREVIEW_STATE_DIM:
        raise ValueError(f"a network with the path preview reads states of {PREVIEW_STATE_DIM} values (the "
                         f"{STATE_DIM} of SPEC §4 and the preview: build_states(..., preview=True), "
                         f"IDCModel(preview=True)); got {states.shape[-1]}")
    phi = states[..., PHI]
    zero = xp.zeros_like(phi)
    ego = xp.stack([zero, zero, states[..., VX] / SPEED_SCALE_MPS, states[..., VY] / SPEED_SCALE_MPS, zero,
                    states[..., OMEGA] / YAW_RATE_SCALE, states[..., DELTA] / STEER_MAX,
                    states[..., ACC] / abs(ACCEL_MIN)], axis=-1)
    track = xp.stack([states[..., DX] / TRACK_POSITION_SCALE_M, states[..., DY] / TRACK_POSITION_SCALE_M,
                      states[..., DV] / SPEED_SCALE_MPS, states[..., DPHI] / ANGLE_SCALE], axis=-1)
    o = others_block(states)
    ahead, lateral = _ego_frame(xp, states, o)
    rel = xp.stack([ahead / POSITION_SCALE_M, lateral / POSITION_SCALE_M,
                    o[..., O_V] / SPEED_SCALE_MPS, xp.wrap(o[..., O_PHI] - phi[..., None]) / ANGLE_SCALE,
                    o[..., O_L] / SIZE_SCALE_M, o[..., O_W] / SIZE_SCALE_M], axis=-1)
    rel = rel.reshape(tuple(rel.shape[:-2]) + (N_OTHERS * OTHER_STATE_DIM,))
    parts = [ego, track, rel]
    if preview:
        path_ahead = states[..., PREVIEW]
        scale = xp.asarray([PREVIEW_LATERAL_SCALE_M] * N_PREVIEW + [ANGLE_SCALE] * N_PREVIEW
                           + [SPEED_SCALE_MPS] * N_PREVIEW, like=path_ahead)
        parts.append(path_ahead / scale)
    if lead:
        parts.append(_lead(xp, states, o, ahead, lateral))
    return xp.concat(parts, axis=-1)


# the divisors of network_input, per column: x_ego's (1 where the column is kept as it is or zeroed),
# x_track's, a participant's (1 where its column is computed otherwise) and the path preview's
_EGO_SCALES = (1.0, 1.0, SPEED_SCALE_MPS, SPEED_SCALE_MPS, 1.0, YAW_RATE_SCALE, STEER_MAX, abs(ACCEL_MIN))
_POSE_COLUMNS = [PX, PY, PHI]  # x_ego's absolute pose, replaced by 0
_TRACK_SCALES = (TRACK_POSITION_SCALE_M, TRACK_POSITION_SCALE_M, SPEED_SCALE_MPS, ANGLE_SCALE)
_OTHER_SCALES = (1.0, 1.0, SPEED_SCALE_MPS, 1.0, SIZE_SCALE_M, SIZE_SCALE_M)
_PREVIEW_SCALES = (PREVIEW_LATERAL_SCALE_M,) * N_PREVIEW + (ANGLE_SCALE,) * N_PREVIEW + (SPEED_SCALE_MPS,) * N_PREVIEW


def candidates_input(states: np.ndarray, preview: bool = False, lead: bool = False,
                     xp: type[NumpyOps] = NumpyOps) -> np.ndarray:
    """:func:`network_input` of the candidates' states of one step (``states`` (n, W), float32 or
    float64, numpy), whose rows share x_ego and x_other as :func:`build_states` makes them: those
    are normalised once, from the first row, and x_track and the path preview row by row.

    The same operations on the same floats as :func:`network_input` (elementwise, each value on its
    own: a division by 1 leaves a value as it is, a product is the same either way round), so the
    same numbers bit for bit with ``xp`` its namespace, in a few numpy calls on a (16, 6) block
    instead of some sixty on stacked (n, 16) columns: the online decision's normalisation
    (:class:`crossroads.idc.decision.IdcController`). Rows that do not share them get the first
    row's x_ego and x_other: check with :func:`rows_share_ego_and_others` where that can happen."""
    if preview and states.shape[-1] != PREVIEW_STATE_DIM:
        return network_input(states, preview, lead, xp)  # its error
    dtype = states.dtype.type
    width = PREVIEW_STATE_DIM if preview else STATE_DIM
    out = np.empty((len(states), width + (LEAD_DIM if lead else 0)), dtype=dtype)
    first = states[0]
    ego = first[EGO] / np.array(_EGO_SCALES, dtype)
    ego[_POSE_COLUMNS] = 0.0
    out[:, EGO] = ego
    out[:, TRACK] = states[:, TRACK] / np.array(_TRACK_SCALES, dtype)
    others = first[OTHERS].reshape(N_OTHERS, OTHER_STATE_DIM)
    out[:, OTHERS] = _others_input(xp, others, first[PX:PY + 1], first[PHI:PHI + 1]).reshape(-1)
    if preview:
        out[:, PREVIEW] = states[:, PREVIEW] / np.array(_PREVIEW_SCALES, dtype)
    if lead:
        out[:, width:] = _lead_of_row(xp, first, others)
    return out


def _lead_of_row(xp: type[NumpyOps], state: np.ndarray, others: np.ndarray) -> np.ndarray:
    """:func:`_lead` of one state (W,) and its participants (16, 6), the same operations on the
    same floats, with the nearest picked by plain indexing (``np.take_along_axis`` costs more than
    the rest on one row)."""
    row, o = state[None], others[None]
    ahead, lateral = _ego_frame(xp, row, o)
    phi, vx = state[PHI], state[VX]
    reach = 0.5 * (o[..., O_W] + EGO_WIDTH_M) + LEAD_LATERAL_MARGIN_M
    inside = (ahead > 0.0) & (xp.abs(lateral) < reach)
    gap = xp.clip(ahead - 0.5 * (o[..., O_L] + EGO_LENGTH_M), 0.0, LEAD_LOOKAHEAD_M)
    gap = xp.where(inside, gap, LEAD_LOOKAHEAD_M)
    k = int(gap[0].argmin())
    along = o[..., O_V] * xp.cos(o[..., O_PHI] - phi[None, None])
    present = inside[0, k].astype(gap.dtype)
    return np.array([gap[0, k] / LEAD_LOOKAHEAD_M, present * (vx - along[0, k]) / SPEED_SCALE_MPS, present],
                    dtype=state.dtype)


def _others_input(xp: type[NumpyOps], others: np.ndarray, position: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """x_other's part of :func:`network_input` (16, 6) for an ego at ``position`` (x, y) heading
    ``phi`` (each an array of the states' dtype): the arithmetic of :func:`_ego_frame` and
    :func:`network_input`, column by column."""
    c, s = xp.cos(phi), xp.sin(phi)
    d = others[:, O_PX:O_PY + 1] - position  # [dx, dy]
    cd, sd = d * c, d * s  # [c·dx, c·dy], [s·dx, s·dy]
    out = others / np.array(_OTHER_SCALES, others.dtype)
    np.add(cd[:, 0], sd[:, 1], out=out[:, O_PX])  # ahead = c·dx + s·dy
    np.subtract(cd[:, 1], sd[:, 0], out=out[:, O_PY])  # lateral = c·dy − s·dx
    out[:, O_PX:O_PY + 1] /= POSITION_SCALE_M
    out[:, O_PHI] = xp.wrap(others[:, O_PHI] - phi) / ANGLE_SCALE
    return out


def rows_share_ego_and_others(states: np.ndarray) -> bool:
    """Whether every row of ``states`` (n, W) has the first row's x_ego and x_other, value for value
    (what :func:`candidates_input` needs; a NaN is never equal)."""
    head = states[:, :OTHERS.stop]
    return bool((head[1:, EGO] == head[0, EGO]).all() and (head[1:, OTHERS] == head[0, OTHERS]).all())
