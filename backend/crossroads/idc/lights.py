"""Online traffic-light logic (SPEC §7, paper Sec. IV-E and its flowchart): pass or stop mode.

Evaluated at every step, in this order:

1. congestion ahead — the front vehicle has been stopped for more than 3 s → stop;
2. the ego is past the stop line → pass (it is inside the intersection: clear it);
3. red (C1 = R) → stop;
4. yellow (C1 = Y) and C2 (it can stop before the line before red) → stop;
5. **(choice)** yellow, not C2, and the line out of reach before red even at full acceleration
   (:func:`can_reach_line_before_red`) → stop;
6. otherwise (green, or yellow but too late to stop and near enough to clear the line) → pass.

C2 (:func:`can_stop_before_red`): braking at a_M = −2.4 m/s² (80 % of the maximal deceleration)
from v needs D_e = v² / (2|a_M|) and t_e = v / |a_M|. The paper prints v²/(2a_M) and v/a_M with a
negative a_M; the magnitudes are meant (a distance and a duration). C2 = D_y ≥ D_e and t_y ≥ t_e,
D_y the distance to the stop line, t_y the remaining yellow time.

Why step 5: the paper gives the pass mode when C2 fails "to encourage rushing before the red
lights". Evaluated at every step, C2 also fails for a slow ego far from the line as the yellow runs
out (t_y < t_e), where no rushing beats the red. Measured (the shipped APG with the shield, the
nominal left turn with a 150 s timeout, 200 seeds): 9 crossed the line on red, 8 of them within
2.7 s of its start; seed 1428211589 was in the stop mode with its bumper 3.8 m short of the line at
0.6 m/s, sped up to 2.3 m/s along the stop profile, got the pass mode 0.6 s before red at 2.0 m
(D_e 1.1 m, but t_e 0.96 s) and crossed 0.8 s into the red. Step 5 keeps the stop mode there.
"""

from __future__ import annotations

from typing import Literal

from crossroads.constants import ACCEL_MAX, CONGESTION_STOP_S, YELLOW_BRAKE_DECEL

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


def can_reach_line_before_red(
    *, distance_to_stop_line_m: float, speed_mps: float, yellow_remaining_s: float,
    accel_mps2: float = ACCEL_MAX,
) -> bool:
    """Whether the front bumper, accelerating at ``accel_mps2`` (the most the ego can) from
    ``speed_mps``, reaches the stop line before the yellow ends: D_y ≤ v t_y + a t_y² / 2."""
    t = max(float(yellow_remaining_s), 0.0)
    v = max(float(speed_mps), 0.0)
    return distance_to_stop_line_m <= v * t + 0.5 * accel_mps2 * t * t


def light_holds_at_line(
    *, past_stop_line: bool, light: str, distance_to_stop_line_m: float, speed_mps: float,
    yellow_remaining_s: float,
) -> bool:
    """Whether the light itself makes the ego stop at the line (steps 2–5 of the module docstring):
    not past it, and red, or yellow with C2 or with the line out of reach before red. The safety
    shield treats the line as a standing obstacle exactly then (:mod:`crossroads.idc.shield`)."""
    if light not in LIGHTS:
        raise ValueError(f"unknown light {light!r}; expected one of {LIGHTS}")
    if past_stop_line:
        return False
    if light == "red":
        return True
    if light == "yellow":
        where = {"distance_to_stop_line_m": distance_to_stop_line_m, "speed_mps": speed_mps,
                 "yellow_remaining_s": yellow_remaining_s}
        return can_stop_before_red(**where) or not can_reach_line_before_red(**where)
    return False


def choose_speed_mode(
    *, front_vehicle_stopped_s: float, past_stop_line: bool, light: str,
    distance_to_stop_line_m: float, speed_mps: float, yellow_remaining_s: float,
) -> SpeedMode:
    """The speed mode of the flowchart (module docstring); ``light`` is "green" | "yellow" | "red"."""
    holds = light_holds_at_line(past_stop_line=past_stop_line, light=light,
                                distance_to_stop_line_m=distance_to_stop_line_m, speed_mps=speed_mps,
                                yellow_remaining_s=yellow_remaining_s)
    return speed_mode_from(holds, front_vehicle_stopped_s)


def speed_mode_from(holds_at_line: bool, front_vehicle_stopped_s: float) -> SpeedMode:
    """The flowchart's mode from :func:`light_holds_at_line` and the congestion rule (step 1), for
    callers that need both the mode and whether the light holds the ego (the safety shield's line)."""
    return "stop" if holds_at_line or front_vehicle_stopped_s > CONGESTION_STOP_S else "pass"
