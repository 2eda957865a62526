"""Yielding to crossing traffic: the ego's timing, the bodies' reach, and where the line lies."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crossroads.constants import DT_S, EGO_WIDTH_M
from crossroads.idc.conflicts import (
    CLEARANCE_M,
    LINE_MARGIN_M,
    MOVING_MPS,
    crossing,
    nearest_conflict_m,
    reach_m,
    time_to_cover_s,
)
from crossroads.idc.shield import predicted_others

STEPS = 80  # 8 s
PATH_X = np.arange(0.0, 60.01, 0.5)
PATH = np.column_stack([PATH_X, np.zeros_like(PATH_X)])  # straight along +x
HEADING = np.zeros(len(PATH_X))


def car(x: float, y: float, v: float, phi: float) -> np.ndarray:
    return np.array([[x, y, v, phi, 4.8, 1.8]])


def predicted(others: np.ndarray) -> np.ndarray:
    return predicted_others(others, np.zeros(len(others)), STEPS)[0]


def test_time_to_cover_follows_the_capped_ramp() -> None:
    """Stepping the ramp at 1 ms gives the same times as the closed form, below and above the cap."""
    v, s, t, times = 2.0, 0.0, 0.0, {}
    targets = [1.0, 10.0, 40.0]
    while len(times) < len(targets):
        v = min(v + 1.5 * 1e-3, 6.0)
        s += v * 1e-3
        t += 1e-3
        for d in targets:
            if d not in times and s >= d:
                times[d] = t
    closed = time_to_cover_s(np.array(targets), 2.0, 1.5, 6.0)
    assert closed == pytest.approx([times[d] for d in targets], abs=2e-3)
    assert time_to_cover_s(np.array([16.0]), 8.0, 1.5, 6.0)[0] == pytest.approx(2.0)  # faster than the cap: keeps it


def test_reach_across_and_alongside() -> None:
    assert reach_m(np.array(1.0), np.array(0.0), np.array(4.8), np.array(1.8)) == pytest.approx(EGO_WIDTH_M / 2 + 2.4 + CLEARANCE_M)
    assert reach_m(np.array(0.0), np.array(-1.0), np.array(4.8), np.array(1.8)) == pytest.approx(EGO_WIDTH_M / 2 + 0.9 + CLEARANCE_M)


def test_a_car_crossing_before_the_ego_could_clear_claims_its_stretch() -> None:
    """Standing, the ego could reach a lane at x = 20 in 4.8 s at the earliest and be across it in
    7.5 s; a car 35 m off at 10 m/s is on it from 3.1 to 3.9 s, less than GAP_S before: the line lies
    short of where the car's body comes within the clearance of the path."""
    line = nearest_conflict_m(PATH, HEADING, PATH_X, 0.0, 0.0, predicted(car(20.0, 35.0, 10.0, -math.pi / 2)))
    first_point = 20.0 - (EGO_WIDTH_M / 2 + 2.4 + CLEARANCE_M)  # where the reach first touches the path
    assert line == pytest.approx(first_point - LINE_MARGIN_M, abs=1.0)  # the check's 1 m resolution


def test_no_line_where_the_ego_clears_first_or_the_car_is_gone() -> None:
    # at 8 m/s the ego is past x = 20 with its rear in ~3.3 s; the car is 60 m off at 10 m/s: 6 s
    assert nearest_conflict_m(PATH, HEADING, PATH_X, 0.0, 8.0, predicted(car(20.0, 60.0, 10.0, -math.pi / 2))) is None
    # the car has crossed already and drives away
    assert nearest_conflict_m(PATH, HEADING, PATH_X, 0.0, 0.0, predicted(car(20.0, -6.0, 10.0, -math.pi / 2))) is None
    # it crosses behind the ego's front
    assert nearest_conflict_m(PATH, HEADING, PATH_X, 30.0, 0.0, predicted(car(20.0, 30.0, 10.0, -math.pi / 2))) is None
    # nobody
    assert nearest_conflict_m(PATH, HEADING, PATH_X, 0.0, 0.0, np.zeros((STEPS, 0, 6))) is None


def test_the_line_stays_put_as_the_car_comes() -> None:
    """The claimed stretch is where the car's path meets the ego's, not where their windows first
    overlap point by point: the line does not creep toward the standing ego as the car nears."""
    lines = [nearest_conflict_m(PATH, HEADING, PATH_X, 0.0, 0.0, predicted(car(20.0, y, 10.0, -math.pi / 2)))
             for y in (60.0, 50.0, 40.0, 35.0)]
    assert max(lines) - min(lines) < 1.1  # the check's 1 m resolution
    # 20 m off, the car is across in 2.4 s, and the standing ego could not be there before 4.5 s
    assert nearest_conflict_m(PATH, HEADING, PATH_X, 0.0, 0.0, predicted(car(20.0, 20.0, 10.0, -math.pi / 2))) is None


def test_who_crosses() -> None:
    others = np.vstack([car(20.0, 30.0, 10.0, -math.pi / 2),  # crossing
                        car(10.0, 0.0, 8.0, 0.0),  # ahead on the path, heading along it
                        car(20.0, 3.5, 8.0, math.pi),  # oncoming alongside
                        car(20.0, 10.0, MOVING_MPS / 2, -math.pi / 2)])  # standing
    assert crossing(others, PATH, HEADING).tolist() == [True, False, True, False]
    assert crossing(np.zeros((0, 6)), PATH, HEADING).shape == (0,)


def test_prediction_steps_are_those_of_the_horizon() -> None:
    """The car's row i is after i + 1 steps: 30 m at 10 m/s is reached on row 29."""
    rows = predicted(car(20.0, 30.0, 10.0, -math.pi / 2))
    assert rows[29, 0, 1] == pytest.approx(30.0 - 30 * DT_S * 10.0)
