"""Online traffic-light logic (SPEC §7, paper Sec. IV-E and its flowchart): pass or stop mode.

Evaluated at every step, in this order:

1. congestion ahead — the front vehicle has been stopped for more than 3 s → stop;
2. the ego is past the stop line → pass (it is inside the intersection: clear it);
3. red (C1 = R) → stop;
4. yellow (C1 = Y) and C2 (it can stop before the line before red) → stop;
5. otherwise (green, or yellow but too late to stop) → pass.

C2 (:func:`can_stop_before_red`): braking at a_M = −2.4 m/s² (80 % of the maximal deceleration)
from v needs D_e = v² / (2|a_M|) and t_e = v / |a_M|. The paper prints v²/(2a_M) and v/a_M with a
negative a_M; the magnitudes are meant (a distance and a duration). C2 = D_y ≥ D_e and t_y ≥ t_e,
D_y the distance to the stop line, t_y the remaining yellow time.
"""

from __future__ import annotations

from typing import Literal

from crossroads.constants import CONGESTION_STOP_S, YELLOW_BRAKE_DECEL

SpeedMode = Literal["pass", "stop"]
LIGHTS = ("green", "yellow", "red")


def braking_needs(speed_mps: float, decel_mps2: float = YELLOW_BRAKE_DECEL) -> tuple[float, float]:
    """(D_e [m], t_e [s]): distance and time to stop from ``speed_mps`` at constant ``decel_mps2``."""
    a = abs(decel_mps2)
    v = max(float(speed_mps), 0.0)
    return v * v / (2.0 * a), v / a


def can_stop_before_red(
    *, distance_to_stop_line_m: float, speed_mps: float, yellow_remaining_s: float,
    decel_mps2: float = YELLOW_BRAKE_DECEL,
) -> bool:
    """C2: D_y ≥ D_e and t_y ≥ t_e (module docstring)."""
    d_e, t_e = braking_needs(speed_mps, decel_mps2)
    return distance_to_stop_line_m >= d_e and yellow_remaining_s >= t_e


def choose_speed_mode(
    *, front_vehicle_stopped_s: float, past_stop_line: bool, light: str,
    distance_to_stop_line_m: float, speed_mps: float, yellow_remaining_s: float,
) -> SpeedMode:
    """The speed mode of the flowchart (module docstring); ``light`` is "green" | "yellow" | "red"."""
    if light not in LIGHTS:
        raise ValueError(f"unknown light {light!r}; expected one of {LIGHTS}")
    if front_vehicle_stopped_s > CONGESTION_STOP_S:
        return "stop"
    if past_stop_line:
        return "pass"
    if light == "red":
        return "stop"
    if light == "yellow" and can_stop_before_red(
        distance_to_stop_line_m=distance_to_stop_line_m, speed_mps=speed_mps,
        yellow_remaining_s=yellow_remaining_s,
    ):
        return "stop"
    return "pass"
