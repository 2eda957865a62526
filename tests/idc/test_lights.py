"""The traffic-light flowchart (SPEC §7): one test per branch, and C2."""

from __future__ import annotations

import pytest

from crossroads.constants import ACCEL_MAX, CONGESTION_STOP_S, YELLOW_BRAKE_DECEL, YELLOW_S
from crossroads.idc.lights import (braking_needs, can_reach_line_before_red, can_stop_before_red, choose_speed_mode,
                                   light_holds_at_line)


def mode(**kw) -> str:
    args = dict(front_vehicle_stopped_s=0.0, past_stop_line=False, light="green",
                distance_to_stop_line_m=50.0, speed_mps=5.0, yellow_remaining_s=YELLOW_S)
    args.update(kw)
    return choose_speed_mode(**args)


def test_congestion_ahead_stops_whatever_else() -> None:
    assert mode(front_vehicle_stopped_s=CONGESTION_STOP_S + 0.1) == "stop"
    assert mode(front_vehicle_stopped_s=CONGESTION_STOP_S + 0.1, past_stop_line=True) == "stop"
    assert mode(front_vehicle_stopped_s=CONGESTION_STOP_S) == "pass"  # "over 3 s": strictly more


def test_past_the_stop_line_passes_even_on_red() -> None:
    assert mode(past_stop_line=True, light="red") == "pass"
    assert mode(past_stop_line=True, light="yellow", speed_mps=1.0) == "pass"


def test_red_stops() -> None:
    assert mode(light="red") == "stop"
    assert mode(light="red", distance_to_stop_line_m=0.5, speed_mps=15.0) == "stop"


def test_yellow_and_able_to_stop_stops() -> None:
    # v = 4.8 m/s: D_e = 4.8 m, t_e = 2 s
    assert mode(light="yellow", speed_mps=4.8, distance_to_stop_line_m=5.0, yellow_remaining_s=2.5) == "stop"


def test_yellow_but_too_close_passes() -> None:
    assert mode(light="yellow", speed_mps=4.8, distance_to_stop_line_m=4.0, yellow_remaining_s=2.5) == "pass"


def test_yellow_too_little_time_to_stop_passes_where_the_line_is_within_reach() -> None:
    # t_e = 2 s > t_y: not C2; 1.5 s at 4.8 m/s and full acceleration cover 8.9 m ≥ 6 m
    assert mode(light="yellow", speed_mps=4.8, distance_to_stop_line_m=6.0, yellow_remaining_s=1.5) == "pass"


def test_yellow_too_little_time_to_stop_stops_where_no_rushing_beats_the_red() -> None:
    """The (choice) step 5: not C2, but the line out of reach before red, so passing would only run
    the red; among them the measured case (seed 1428211589: 2.31 m/s, 1.96 m, 0.6 s of yellow)."""
    assert mode(light="yellow", speed_mps=4.8, distance_to_stop_line_m=50.0, yellow_remaining_s=1.5) == "stop"
    assert mode(light="yellow", speed_mps=2.31, distance_to_stop_line_m=1.96, yellow_remaining_s=0.6) == "stop"


def test_green_passes() -> None:
    assert mode(light="green") == "pass"
    assert mode(light="green", speed_mps=0.0, distance_to_stop_line_m=1.0) == "pass"


def test_c2() -> None:
    a = abs(YELLOW_BRAKE_DECEL)
    d_e, t_e = braking_needs(12.0)
    assert d_e == pytest.approx(144.0 / (2 * a)) and t_e == pytest.approx(12.0 / a)
    assert can_stop_before_red(distance_to_stop_line_m=d_e, speed_mps=12.0, yellow_remaining_s=t_e)
    assert not can_stop_before_red(distance_to_stop_line_m=d_e - 0.01, speed_mps=12.0, yellow_remaining_s=t_e)
    assert not can_stop_before_red(distance_to_stop_line_m=d_e, speed_mps=12.0, yellow_remaining_s=t_e - 0.01)
    assert can_stop_before_red(distance_to_stop_line_m=0.0, speed_mps=0.0, yellow_remaining_s=0.0)


def test_reach_before_red() -> None:
    reach = 3.0 * 1.2 + 0.5 * ACCEL_MAX * 1.2 * 1.2
    assert can_reach_line_before_red(distance_to_stop_line_m=reach, speed_mps=3.0, yellow_remaining_s=1.2)
    assert not can_reach_line_before_red(distance_to_stop_line_m=reach + 0.01, speed_mps=3.0, yellow_remaining_s=1.2)
    assert can_reach_line_before_red(distance_to_stop_line_m=0.0, speed_mps=0.0, yellow_remaining_s=0.0)
    assert not can_reach_line_before_red(distance_to_stop_line_m=0.1, speed_mps=5.0, yellow_remaining_s=-0.1)


def test_unknown_light() -> None:
    with pytest.raises(ValueError):
        mode(light="blue")


def test_the_line_holds_the_ego_where_the_light_stops_it_and_not_for_congestion() -> None:
    """light_holds_at_line (the safety shield's line) is the stop mode less the congestion rule."""
    for light in ("green", "yellow", "red"):
        for past in (False, True):
            for distance, speed, left in ((50.0, 5.0, YELLOW_S), (3.0, 8.0, 1.0), (30.0, 1.0, 0.5), (1.0, 0.0, 2.0)):
                where = dict(past_stop_line=past, light=light, distance_to_stop_line_m=distance, speed_mps=speed,
                             yellow_remaining_s=left)
                holds = light_holds_at_line(**where)
                assert holds == (mode(**where) == "stop")
                assert mode(**where, front_vehicle_stopped_s=CONGESTION_STOP_S + 1.0) == "stop"
    assert not light_holds_at_line(past_stop_line=False, light="green", distance_to_stop_line_m=5.0, speed_mps=5.0,
                                   yellow_remaining_s=YELLOW_S)
    assert light_holds_at_line(past_stop_line=False, light="red", distance_to_stop_line_m=5.0, speed_mps=5.0,
                               yellow_remaining_s=0.0)
    with pytest.raises(ValueError, match="blue"):
        light_holds_at_line(past_stop_line=False, light="blue", distance_to_stop_line_m=5.0, speed_mps=5.0,
                            yellow_remaining_s=0.0)
