"""SUMO's driver brakes for a pedestrian, cyclist or vehicle in its way ahead: the corridors'
geometry and the commands it gives SUMO."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crossroads.geometry import arc_lengths

from crossroads.sim.look_ahead import (
    BUFFER_M,
    COMFORT_DECEL_MPS2,
    VEHICLE_BUFFER_M,
    VEHICLE_DECEL_MPS2,
    LATERAL_MARGIN_M,
    LookAhead,
    WayAhead,
    body_sweeps_into,
    corridor_length,
    footprint_points,
    in_front,
    in_the_way,
    vehicle_corridor_length,
    vehicles_in_the_way,
)

LENGTH, WIDTH = 4.8, 2.0  # the ego's; it stands at the origin heading east, its front bumper at x = 2.4
RADIUS = 0.25  # a pedestrian's


def _in_the_way(x: float, y: float, heading: float = 0.0, speed: float = 0.0, ego_speed: float = 0.0) -> bool:
    return bool(in_the_way(0.0, 0.0, 0.0, ego_speed, LENGTH, WIDTH, np.array([x]), np.array([y]),
                           np.array([heading]), np.array([speed]), np.array([RADIUS]))[0])


def test_the_corridor_is_the_braking_distance_and_a_buffer() -> None:
    assert corridor_length(0.0) == BUFFER_M
    assert corridor_length(9.0) == pytest.approx(81.0 / (2.0 * COMFORT_DECEL_MPS2) + BUFFER_M)
    assert corridor_length(-1.0) == BUFFER_M  # no negative speeds


def test_someone_standing_in_front_of_the_bumper_is_in_the_way() -> None:
    assert _in_the_way(3.0, 0.0)  # 0.6 m ahead of the bumper
    assert _in_the_way(3.0, 1.4)  # off the ego's side line, but its body and the margin reach in
    assert not _in_the_way(3.0, 1.7)  # beside the corridor
    assert not _in_the_way(2.4 + BUFFER_M + 1.0, 0.0)  # beyond it, the ego standing
    assert _in_the_way(2.4 + BUFFER_M + 1.0, 0.0, ego_speed=6.0)  # within it at 6 m/s


def test_someone_about_to_walk_into_the_corridor_is_in_the_way() -> None:
    assert _in_the_way(3.5, 2.5, heading=-math.pi / 2, speed=1.3)  # there within the second
    assert not _in_the_way(3.5, 2.5, heading=math.pi / 2, speed=1.3)  # walking away
    assert not _in_the_way(3.5, 4.0, heading=-math.pi / 2, speed=1.3)  # too far to be there in a second


def test_in_front_is_where_setting_off_would_touch_no_margin_beside_the_egos_width() -> None:
    def front(x: float, y: float) -> bool:
        return bool(in_front(0.0, 0.0, 0.0, LENGTH, WIDTH, np.array([x]), np.array([y]), np.array([RADIUS]))[0])

    assert front(2.8, 1.2)  # 0.4 m ahead of the bumper, its body over the ego's side line
    assert not front(2.8, 1.3)  # clear of it by 0.05 m: the ego drives past
    assert not front(2.4 + BUFFER_M + 0.3, 0.0)  # beyond the buffer
    assert not front(0.0, 1.2) and not front(-3.0, 0.0)  # beside or behind


def test_behind_or_beside_the_ego_is_not_in_the_way() -> None:
    assert not _in_the_way(-4.0, 0.0)
    assert not _in_the_way(0.0, 1.8, heading=0.0, speed=1.3)  # walking along its side


class _Session:
    """Records the speeds commanded to the ego."""

    def __init__(self) -> None:
        self.commands: list[tuple[str, float]] = []

    def set_speed(self, vid: str, speed: float) -> None:
        self.commands.append((vid, speed))


def _update(rule: LookAhead, session: _Session, x: float) -> bool:
    return rule.update(session, (0.0, 0.0, 0.0, 0.0, LENGTH, WIDTH), np.array([x]), np.array([0.0]),  # type: ignore[arg-type]
                       np.array([0.0]), np.array([0.0]), np.array([RADIUS]))


def test_it_stops_the_ego_once_and_hands_it_back_when_the_way_is_clear() -> None:
    rule, session = LookAhead("ego"), _Session()
    assert _update(rule, session, 3.0) and _update(rule, session, 3.0)
    assert session.commands == [("ego", 0.0)]  # one command while it lasts
    assert not _update(rule, session, 40.0)  # gone: SUMO's driver has the ego again
    assert session.commands == [("ego", 0.0), ("ego", -1.0)] and not rule.braking


def test_off_means_off() -> None:
    rule, session = LookAhead("ego", enabled=False), _Session()
    assert not _update(rule, session, 3.0) and session.commands == []


CAR = (4.5, 1.8)  # a car's length and width


def _car_in_the_way(x: float, y: float, heading: float = 0.0, ego_speed: float = 0.0, speed: float = 0.0) -> bool:
    return bool(vehicles_in_the_way(0.0, 0.0, 0.0, ego_speed, LENGTH, WIDTH, np.array([x]), np.array([y]),
                                    np.array([heading]), np.array([speed]), np.array([CAR[0]]),
                                    np.array([CAR[1]]))[0])


def test_a_car_s_footprint_points_are_its_corners_sides_and_centre() -> None:
    px, py = footprint_points(np.array([10.0]), np.array([5.0]), np.array([math.pi / 2]), np.array([4.0]),
                              np.array([2.0]))
    points = set(zip(np.round(px[0], 6).tolist(), np.round(py[0], 6).tolist()))
    assert {(9.0, 3.0), (11.0, 3.0), (9.0, 7.0), (11.0, 7.0), (10.0, 5.0)} <= points and len(points) == 9


def test_a_vehicle_s_corridor_is_the_ego_s_braking_distance_and_a_metre() -> None:
    assert vehicle_corridor_length(0.0) == VEHICLE_BUFFER_M
    assert vehicle_corridor_length(8.0) == pytest.approx(64.0 / (2.0 * VEHICLE_DECEL_MPS2) + VEHICLE_BUFFER_M)


def test_a_leader_at_its_standstill_gap_is_not_in_the_way_and_a_corner_over_the_bumper_is() -> None:
    """SUMO keeps 2.5 m to a leader at a standstill: no braking for it. A left-turner turned 10°
    whose rear corner reaches 0.3 m in front of the bumper: braking (a_single_lane, seed 179128172)."""
    assert not _car_in_the_way(2.4 + 2.5 + 2.25, 0.0)
    assert _car_in_the_way(2.4 + 2.5 + 2.25, 0.0, ego_speed=6.0)  # closing in at 6 m/s
    heading = math.radians(10.0)
    corner_x = 2.4 + 0.3  # where the rear right corner lies
    centre_x = corner_x + 2.25 * math.cos(heading) - 0.9 * math.sin(heading)
    centre_y = 2.25 * math.sin(heading) + 0.9 * math.cos(heading) - 0.9
    assert _car_in_the_way(centre_x, centre_y, heading)


def test_a_car_crossing_ahead_is_in_the_way_one_beside_or_behind_is_not() -> None:
    assert _car_in_the_way(2.4 + 0.8 + 0.9, 0.0, heading=math.pi / 2)  # across the corridor, 0.8 m ahead
    assert not _car_in_the_way(2.4, 3.3)  # alongside in the next lane
    assert not _car_in_the_way(-7.0, 0.0)  # the follower


def test_a_car_about_to_cut_across_the_corridor_is_in_the_way() -> None:
    """A car coming in from the side, as at the merge of two turns into one exit, is in the way
    before it gets there; one driving away, or along the next lane, is not."""
    assert _car_in_the_way(3.0, -5.5, heading=math.pi / 2, speed=5.0)  # in the corridor within the second
    assert not _car_in_the_way(3.0, -5.5, heading=-math.pi / 2, speed=5.0)  # driving away
    assert not _car_in_the_way(3.0, -5.5, heading=math.pi / 2)  # standing there
    assert not _car_in_the_way(0.0, 3.3, heading=0.0, speed=12.0)  # overtaking in the next lane


def test_a_vehicle_in_the_way_stops_the_ego_too() -> None:
    rule, session = LookAhead("ego"), _Session()
    nobody = (np.array([]), np.array([]), np.array([]), np.array([]), np.array([]), np.array([]))
    car = (np.array([2.4 + 0.5 + 2.25]), np.array([0.0]), np.array([0.0]), np.array([0.0]), np.array([CAR[0]]),
           np.array([CAR[1]]))
    ego = (0.0, 0.0, 0.0, 0.0, LENGTH, WIDTH)
    assert rule.update(session, ego, *nobody[:5], vehicles=car)  # type: ignore[arg-type]
    assert not rule.update(session, ego, *nobody[:5], vehicles=nobody)  # type: ignore[arg-type]
    assert session.commands == [("ego", 0.0), ("ego", -1.0)]


def _left_turn() -> np.ndarray:
    """A way straight north up to (0, 0), then a left turn of radius 10 m round (-10, 0) (1° steps)."""
    a = np.radians(np.arange(0.0, 91.0))
    turn = np.column_stack([-10.0 + 10.0 * np.cos(a), 10.0 * np.sin(a)])
    return np.vstack([[(0.0, -10.0)], turn])


def _sweeps(way: np.ndarray, front_m: float, car: tuple[float, float, float], reach_m: float = 3.0) -> bool:
    x, y, heading = car
    return bool(body_sweeps_into(WayAhead(way, arc_lengths(way), front_m), reach_m, LENGTH, WIDTH, np.array([x]),
                                 np.array([y]), np.array([heading]), np.array([CAR[0]]), np.array([CAR[1]]))[0])


def test_the_ego_turning_sweeps_into_a_car_standing_over_its_bend_that_its_heading_points_past() -> None:
    way = _left_turn()  # the ego's front at (0, 0) (10 m along), heading north, about to turn left
    x, y, heading = -4.0, 4.5, -math.pi / 4  # a car standing across the bend, left of the heading's line
    reach = vehicle_corridor_length(5.0)  # at 5 m/s
    assert _sweeps(way, 10.0, (x, y, heading), reach_m=reach)
    assert not vehicles_in_the_way(0.0, -2.4, math.pi / 2, 5.0, LENGTH, WIDTH, np.array([x]), np.array([y]),
                                   np.array([heading]), np.array([0.0]), np.array([CAR[0]]),
                                   np.array([CAR[1]]))[0]  # the straight corridor points past it
    assert not _sweeps(way, 10.0, (x, y, heading), reach_m=0.5)  # not within half a metre


def test_a_car_the_ego_leaves_behind_or_keeps_its_distance_from_is_not_swept_into() -> None:
    way = _left_turn()
    assert not _sweeps(way, 10.0, (0.0, -10.0, math.pi / 2))  # behind the ego's back, in its lane
    assert not _sweeps(way, 10.0, (6.0, 2.0, math.pi / 2))  # beside the turn's outside, 6 m off
    # a car whose side the ego's body is already within the margin of, the ego's way leading it
    # no nearer (alongside, on a straight way): as near as now is not nearer
    straight = np.column_stack([np.zeros(41), np.linspace(-20.0, 20.0, 41)])
    beside = (WIDTH / 2 + CAR[1] / 2 + LATERAL_MARGIN_M / 2, 0.0, math.pi / 2)
    assert not _sweeps(straight, 22.4, beside)


def test_the_swept_body_stops_the_ego_inside_the_junction() -> None:
    rule, session = LookAhead("ego"), _Session()
    nobody = (np.array([]), np.array([]), np.array([]), np.array([]), np.array([]))
    way = _left_turn()
    car = (np.array([-4.0]), np.array([4.5]), np.array([-math.pi / 4]), np.array([0.0]), np.array([CAR[0]]),
           np.array([CAR[1]]))
    ego = (0.0, -2.4, math.pi / 2, 5.0, LENGTH, WIDTH)  # 5 m/s: its corridor 3.8 m
    assert not rule.update(session, ego, *nobody, vehicles=car)  # type: ignore[arg-type]  # straight: past it
    assert rule.update(session, ego, *nobody, vehicles=car, way=WayAhead(way, arc_lengths(way), 10.0))  # type: ignore[arg-type]
