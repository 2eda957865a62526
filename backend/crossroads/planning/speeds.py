"""Velocity planning of a candidate path (SPEC §1, paper Sec. III-A): pass and stop profiles.

Pure functions of the arc length ``s`` [m] along a candidate path, given the arc lengths of the
stop line (X1, ``s_stop_line``) and of the exit point (X4, ``s_exit``). Speeds are in m/s.

Segments, as the planner labels its points (:mod:`crossroads.planning.routes`):
``s ≤ s_stop_line`` is the entrance route (X1 itself is on the stop line, still outside),
``s_stop_line < s ≤ s_exit`` the curve route inside the intersection, ``s > s_exit`` the exit route.

Pass mode: 0.8·V_limit outside the intersection, min(0.5·V_limit, 30 km/h) inside.
**(choice)** The change at the stop line (and back at the exit) is a step, as drawn in the paper's
figure: the reference is a target, not a trajectory; the IDC policy smooths it through its
acceleration and jerk limits and its Δv weight. A ramp would only move the target earlier.

Stop mode: 0.8·V_limit until ``decel_distance_m`` (30 m) before the point where the ego's front
bumper meets the stop line, then uniform deceleration to 0 there, ``v = v0·sqrt(d / 30 m)`` with
``d`` the distance left to that point (constant deceleration v0²/(2·30 m) ≈ 1.16 m/s² for V_limit =
37.5 km/h), 0 from there through the intersection, 0.8·V_limit again after the exit point. If the
entrance route is shorter than 30 m the profile simply starts part-way down the deceleration.
**(choice)** That point is ``stop_short_m`` (``constants.STOP_SHORT_M``, half the ego's length)
before the stop line, since ``s`` is the arc length of the ego's centre: the paper says "decelerate
uniformly to the stop line" and counts a violation when the vehicle crosses it.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from crossroads.constants import (
    INSIDE_SPEED_CAP_MPS,
    PASS_SPEED_FACTOR_INSIDE,
    PASS_SPEED_FACTOR_OUTSIDE,
    STOP_DECEL_DISTANCE_M,
    STOP_SHORT_M,
    V_LIMIT_MPS,
)
from crossroads.geometry import FloatArray

SpeedMode = Literal["pass", "stop"]
SPEED_MODES: tuple[SpeedMode, ...] = ("pass", "stop")


def outside_speed(v_limit_mps: float = V_LIMIT_MPS) -> float:
    """Reference speed outside the intersection [m/s]: 0.8·V_limit."""
    return PASS_SPEED_FACTOR_OUTSIDE * v_limit_mps


def inside_speed(v_limit_mps: float = V_LIMIT_MPS) -> float:
    """Pass-mode reference speed inside the intersection [m/s]: min(0.5·V_limit, 30 km/h)."""
    return min(PASS_SPEED_FACTOR_INSIDE * v_limit_mps, INSIDE_SPEED_CAP_MPS)


def _check(s_stop_line: float, s_exit: float, v_limit_mps: float) -> None:
    if not s_exit >= s_stop_line:
        raise ValueError(f"s_exit ({s_exit}) must not lie before s_stop_line ({s_stop_line})")
    if not v_limit_mps > 0.0:
        raise ValueError(f"v_limit_mps must be positive, got {v_limit_mps}")


def _out(values: FloatArray) -> FloatArray | float:
    return float(values) if values.ndim == 0 else values


def pass_speed(
    s: ArrayLike, s_stop_line: float, s_exit: float, v_limit_mps: float = V_LIMIT_MPS
) -> FloatArray | float:
    """Pass-mode reference speed [m/s] at arc length(s) ``s`` [m] (a float for a scalar ``s``)."""
    _check(s_stop_line, s_exit, v_limit_mps)
    ss = np.asarray(s, dtype=np.float64)
    inside = (ss > s_stop_line) & (ss <= s_exit)
    return _out(np.where(inside, inside_speed(v_limit_mps), outside_speed(v_limit_mps)))


def stop_speed(
    s: ArrayLike,
    s_stop_line: float,
    s_exit: float,
    v_limit_mps: float = V_LIMIT_MPS,
    decel_distance_m: float = STOP_DECEL_DISTANCE_M,
    stop_short_m: float = STOP_SHORT_M,
) -> FloatArray | float:
    """Stop-mode reference speed [m/s] at arc length(s) ``s`` [m] of the ego's centre (a float for
    a scalar ``s``): 0 from ``stop_short_m`` before the stop line on (module docstring)."""
    _check(s_stop_line, s_exit, v_limit_mps)
    if not decel_distance_m > 0.0:
        raise ValueError(f"decel_distance_m must be positive, got {decel_distance_m}")
    if stop_short_m < 0.0:
        raise ValueError(f"stop_short_m must be >= 0, got {stop_short_m}")
    ss = np.asarray(s, dtype=np.float64)
    v0 = outside_speed(v_limit_mps)
    rest = s_stop_line - stop_short_m  # where the centre stands when the front bumper is at the line
    to_go = np.clip(rest - ss, 0.0, decel_distance_m)  # distance left to that point [m]
    approach = v0 * np.sqrt(to_go / decel_distance_m)
    v = np.where(ss > s_exit, v0, np.where(ss >= rest, 0.0, approach))
    return _out(v)


def speed_profile(
    mode: SpeedMode,
    s: ArrayLike,
    s_stop_line: float,
    s_exit: float,
    v_limit_mps: float = V_LIMIT_MPS,
) -> FloatArray | float:
    """The reference speed of ``mode`` ("pass" or "stop") at arc length(s) ``s`` [m]."""
    if mode == "pass":
        return pass_speed(s, s_stop_line, s_exit, v_limit_mps)
    if mode == "stop":
        return stop_speed(s, s_stop_line, s_exit, v_limit_mps)
    raise ValueError(f"unknown speed mode {mode!r}; expected one of {', '.join(SPEED_MODES)}")
