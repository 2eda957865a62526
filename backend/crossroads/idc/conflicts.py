"""Crossing traffic on the ego's path: whether someone will be on a stretch of it when the ego is.

**(choice)** Not in the paper; used by the safety shield's decision (:mod:`crossroads.idc.decision`):
while the ego is short of its stop line and crossing traffic claims a stretch of a candidate path
ahead, the stop line is a line for the shield, like a red light or a claimed crosswalk
(:mod:`crossroads.idc.crosswalks`) — gap acceptance at the line. Why: the shield checks the next
4 s of a go-then-brake backup against the participants in the state's 8 vehicle slots. Waiting at
the junction those slots fill with the queues around it, an oncoming car enters them late, and once
the ego is on the oncoming lanes braking leaves it standing in the car's way: oncoming vehicles were
20 of the 38 collisions of 200 nominal left turns with a 150 s timeout (session 21,
docs/measurements/safety-shield.md). Why at the stop line and not short of the claimed stretch,
inside the junction, as first built: SUMO's vehicles drive into an ego standing there (session 22).

The check, per step and candidate path: every perceived vehicle and cyclist that moves
(``MOVING_MPS``) and crosses the path (not heading along it within ``ALONG_PATH_RAD`` where it passes
nearest: the car ahead and the followers are the shield's participant check's) is predicted over
``CONFLICT_HORIZON_S`` keeping its speed along its lanes ahead (:mod:`crossroads.sim.lanes_ahead`;
f_other on its lane's curvature where the map does not say). This gives the stretch of the path it
comes onto and when it is there; the ego's own time on the stretch comes from its speed now,
arriving at its quickest (``ARRIVE_ACCEL_MPS2``) and leaving at its slowest plausible
(``LEAVE_ACCEL_MPS2``). Where the two windows come within ``GAP_S`` of each other, the participant
claims its stretch, and :func:`nearest_conflict_m` gives the distance to a line short of the nearest
claimed stretch.

Pure numpy; participants are predicted at once over the horizon (no Python loop over time).
"""

from __future__ import annotations

import math

import numpy as np

from crossroads.constants import ACCEL_MAX, DT_S, EGO_LENGTH_M, EGO_WIDTH_M
from crossroads.idc.state import O_L, O_PHI, O_PX, O_PY, O_V, O_W

MOVING_MPS = 1.0  # [m/s] slower than this a participant stands: the shield's participant check is for it
ALONG_PATH_RAD = math.radians(30.0)  # [rad] heading along the path this closely: a leader or a follower
CONFLICT_HORIZON_S = 8.0  # [s] how far ahead participants are predicted (at 13.9 m/s: 111 m)
LOOKAHEAD_M = 40.0  # [m] how far along the path ahead of the front bumper conflicts are looked for
ARRIVE_ACCEL_MPS2 = ACCEL_MAX  # [m/s²] the ego's quickest arrival: the acceleration limit
# [m/s²] the ego's slowest plausible clearing: the pass profile's gentle pull-away (as the crosswalks)
LEAVE_ACCEL_MPS2 = 1.0
CLEARING_SPEED_MPS = 6.9  # [m/s] the ego's speed cap while crossing: 0.5·V_limit inside (50 km/h)
GAP_S = 1.5  # [s] the least time between the ego leaving a point and someone reaching it, or the reverse
CLEARANCE_M = 0.5  # [m] between the bodies, on top of their half extents
LINE_MARGIN_M = 1.0  # [m] the line lies this far before the first claimed point
# [m] the line is given up (the ego committed) only once full braking cannot stand short of the
# claimed stretch itself, LINE_MARGIN_M past the line. Why: between steps the line moves by up to the
# check's 1 m resolution and with the perception noise; given up at the line itself, on the nominal
# left turn (150 s, seed 896230294; then a line inside the junction) it was lost one step after the
# ego had last been able to stop
COMMIT_SLACK_M = LINE_MARGIN_M
NEAR_BOX_M = 5.0  # [m] more than any reach: a participant never this near the stretch's box is skipped


def time_to_cover_s(distance_m: np.ndarray, speed_mps: float, accel_mps2: float, cap_mps: float) -> np.ndarray:
    """[s] for the ego to drive ``distance_m`` (n,) from ``speed_mps``, accelerating at ``accel_mps2``
    up to ``cap_mps`` (or keeping its speed if above it): the inverse of a capped ramp."""
    d = np.maximum(np.asarray(distance_m, np.float64), 0.0)
    v0 = max(speed_mps, 0.0)
    cap = max(cap_mps, v0)
    ramp_m = (cap * cap - v0 * v0) / (2.0 * accel_mps2)  # covered while accelerating to the cap
    ramping = (-v0 + np.sqrt(v0 * v0 + 2.0 * accel_mps2 * d)) / accel_mps2
    cruising = (cap - v0) / accel_mps2 + (d - ramp_m) / max(cap, 1e-9)
    return np.where(d <= ramp_m, ramping, cruising)


def reach_m(sin_relative: np.ndarray, cos_relative: np.ndarray, length_m: np.ndarray, width_m: np.ndarray) -> np.ndarray:
    """[m] how close a participant's centre may come to a point of the ego's path before the two
    bodies are within ``CLEARANCE_M``, from the sine and cosine of its heading relative to the
    path's there: the ego's half width plus the participant's half extent across the path (its half
    length when crossing at right angles, its half width alongside)."""
    across = np.abs(sin_relative) * length_m / 2.0 + np.abs(cos_relative) * width_m / 2.0
    return EGO_WIDTH_M / 2.0 + across + CLEARANCE_M


# the check's resolution, why it suffices: at 14 m/s a participant moves 2.8 m in 0.2 s, so its centre
# passes within 1.4 m of the path line at some row, within 1.5 m of a path point 1 m apart — inside
# the least reach across (2.4 m for a car); finer, the check cost 26 ms a decision (3 paths)
TIME_STRIDE = 2  # predicted rows used: every second one (0.2 s)
POINT_STRIDE = 2  # path points used: every second one (the paths are sampled at ≤ 0.5 m)


def nearest_conflict_m(points: np.ndarray, heading: np.ndarray, s: np.ndarray, front_s_m: float,
                       speed_mps: float, predicted: np.ndarray) -> float | None:
    """The front bumper's distance [m] to the line short of the nearest claimed stretch of a path
    (``points`` (n, 2), ``heading`` (n,), arc lengths ``s`` (n,)), the bumper at ``front_s_m`` and
    the ego at ``speed_mps``, against the crossing participants ``predicted`` (steps, k, 6): row i
    after i + 1 steps of ``DT_S``. None when nothing within ``LOOKAHEAD_M`` is claimed."""
    ahead = np.flatnonzero((s >= front_s_m) & (s <= front_s_m + LOOKAHEAD_M))[::POINT_STRIDE]
    if predicted.shape[1] == 0 or len(ahead) == 0:
        return None
    pts, hdg, sa = points[ahead], heading[ahead], s[ahead]
    rows = predicted[TIME_STRIDE - 1::TIME_STRIDE]
    # only who comes near the stretch at all (a box around it): most of the traffic never does
    lo, hi = pts.min(axis=0) - NEAR_BOX_M, pts.max(axis=0) + NEAR_BOX_M
    near = ((rows[:, :, O_PX] >= lo[0]) & (rows[:, :, O_PX] <= hi[0])
            & (rows[:, :, O_PY] >= lo[1]) & (rows[:, :, O_PY] <= hi[1])).any(axis=0)
    if not near.any():
        return None
    rows = rows[:, near]
    dx = rows[:, :, None, O_PX] - pts[None, None, :, 0]  # (steps, k, m)
    dy = rows[:, :, None, O_PY] - pts[None, None, :, 1]
    c, sn = np.cos(rows[:, :, None, O_PHI]), np.sin(rows[:, :, None, O_PHI])
    ch, sh = np.cos(hdg), np.sin(hdg)
    reach = reach_m(sn * ch - c * sh, c * ch + sn * sh, rows[:, :, None, O_L], rows[:, :, None, O_W])
    on = dx * dx + dy * dy <= reach * reach
    zone = on.any(axis=0)  # (k, m): the points each participant comes onto within the horizon
    present = zone.any(axis=1)  # (k,)
    if not present.any():
        return None
    on, zone = on[:, present], zone[present]
    m, steps = zone.shape[1], on.shape[0]
    # each participant's stretch of the path, from the first point it comes onto to the last, and
    # when it is on the stretch: from the path, not per point, so that the line does not creep toward
    # the ego as the participant comes nearer (per point, its windows on the nearer points grew in)
    first_point = zone.argmax(axis=1)
    last_point = m - 1 - zone[:, ::-1].argmax(axis=1)
    on_stretch = on.any(axis=2)  # (steps, k)
    t = (np.arange(steps) + 1.0) * (TIME_STRIDE * DT_S)
    arrives = t[on_stretch.argmax(axis=0)]
    leaves = t[steps - 1 - on_stretch[::-1].argmax(axis=0)]
    # the ego's body covers the stretch from its front reaching the first point until its rear has
    # passed the last: arriving at its quickest, leaving at its slowest plausible
    ego_in = time_to_cover_s(sa[first_point] - front_s_m, speed_mps, ARRIVE_ACCEL_MPS2, CLEARING_SPEED_MPS)
    ego_out = time_to_cover_s(sa[last_point] - front_s_m + EGO_LENGTH_M, speed_mps, LEAVE_ACCEL_MPS2, CLEARING_SPEED_MPS)
    conflicting = (arrives < ego_out + GAP_S) & (ego_in < leaves + GAP_S)
    if not conflicting.any():
        return None
    return float(sa[first_point[conflicting]].min() - front_s_m - LINE_MARGIN_M)


def crossing(others: np.ndarray, points: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """(k,) bool: which of ``others`` (k, 6) the conflict check predicts: moving (``MOVING_MPS``),
    and not heading along the path (``points`` (n, 2), ``heading`` (n,)) within ``ALONG_PATH_RAD``
    where it passes nearest to them — a leader or a follower on the path, or traffic alongside it,
    is the shield's participant check's. Why where the path passes nearest: on the turn, a car
    ahead heads along the path where it is, not where the ego is."""
    o = np.asarray(others, np.float64).reshape(-1, 6)
    if len(o) == 0:
        return np.zeros(0, bool)
    d2 = (o[:, None, O_PX] - points[None, :, 0]) ** 2 + (o[:, None, O_PY] - points[None, :, 1]) ** 2
    near = heading[d2.argmin(axis=1)]
    diff = np.angle(np.exp(1j * (o[:, O_PHI] - near)))
    return (o[:, O_V] >= MOVING_MPS) & (np.abs(diff) >= ALONG_PATH_RAD)
