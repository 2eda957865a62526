"""SUMO's driver brakes for a pedestrian or cyclist in its way ahead: the corridor's geometry and
the commands it gives SUMO."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crossroads.sim.look_ahead import BUFFER_M, COMFORT_DECEL_MPS2, LookAhead, corridor_length, in_the_way

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
