"""Velocity planning (SPEC §1): pass and stop profiles at their key points."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crossroads.constants import EGO_LENGTH_M, KMH, STOP_SHORT_M, V_LIMIT_MPS
from crossroads.planning import (
    inside_speed,
    outside_speed,
    pass_speed,
    plan_candidates,
    speed_profile,
    stop_speed,
)
from planning.factories import four_way_junction

S1, S4 = 50.0, 80.0  # stop line (X1) and exit point (X4) [m]
V0 = 0.8 * V_LIMIT_MPS  # 30 km/h


def test_levels() -> None:
    assert outside_speed() == pytest.approx(30.0 * KMH)
    assert inside_speed() == pytest.approx(0.5 * 37.5 * KMH)  # 18.75 km/h < 30 km/h
    assert inside_speed(80.0 * KMH) == pytest.approx(30.0 * KMH)  # capped at 30 km/h


def test_pass_mode_key_points() -> None:
    assert pass_speed(0.0, S1, S4) == pytest.approx(V0)  # X0
    assert pass_speed(S1 - 30.0, S1, S4) == pytest.approx(V0)
    assert pass_speed(S1, S1, S4) == pytest.approx(V0)  # X1 still outside: a step right after it
    assert pass_speed(S1 + 1e-6, S1, S4) == pytest.approx(inside_speed())
    assert pass_speed(65.0, S1, S4) == pytest.approx(inside_speed())  # inside
    assert pass_speed(S4, S1, S4) == pytest.approx(inside_speed())
    assert pass_speed(S4 + 5.0, S1, S4) == pytest.approx(V0)  # after the exit


def test_stop_mode_key_points() -> None:
    """The profile is of the ego's centre: it reaches 0 where the front bumper meets the line."""
    rest = S1 - STOP_SHORT_M
    assert STOP_SHORT_M == pytest.approx(EGO_LENGTH_M / 2)
    assert stop_speed(0.0, S1, S4) == pytest.approx(V0)  # X0
    assert stop_speed(rest - 30.0, S1, S4) == pytest.approx(V0)  # deceleration starts
    assert stop_speed(rest - 15.0, S1, S4) == pytest.approx(V0 * math.sqrt(0.5))
    assert stop_speed(rest, S1, S4) == 0.0  # the front bumper at the stop line
    assert stop_speed(S1 - 1.0, S1, S4) == 0.0  # the bumper would be past it
    assert stop_speed(S1, S1, S4) == 0.0  # the centre at the stop line
    assert stop_speed(65.0, S1, S4) == 0.0  # inside
    assert stop_speed(S4, S1, S4) == 0.0
    assert stop_speed(S4 + 5.0, S1, S4) == pytest.approx(V0)  # after the exit
    assert stop_speed(S1 - 15.0, S1, S4, stop_short_m=0.0) == pytest.approx(V0 * math.sqrt(0.5))  # the centre's line
    with pytest.raises(ValueError, match="stop_short_m"):
        stop_speed(0.0, S1, S4, stop_short_m=-1.0)


def test_stop_mode_is_uniform_deceleration() -> None:
    rest = S1 - STOP_SHORT_M
    s = np.linspace(rest - 30.0, rest, 301)
    v = stop_speed(s, S1, S4)
    # v² is linear in s: constant deceleration v0²/(2·30 m)
    decel = -np.gradient(v**2, s) / 2.0
    np.testing.assert_allclose(decel, V0**2 / 60.0, rtol=1e-9)
    assert np.all(np.diff(v) <= 0.0)


def test_arrays_and_modes() -> None:
    s = np.array([0.0, 40.0, 60.0, 90.0])
    np.testing.assert_allclose(speed_profile("pass", s, S1, S4), pass_speed(s, S1, S4))
    np.testing.assert_allclose(speed_profile("stop", s, S1, S4), stop_speed(s, S1, S4))
    assert isinstance(pass_speed(3.0, S1, S4), float)
    with pytest.raises(ValueError, match="unknown speed mode"):
        speed_profile("crawl", s, S1, S4)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="s_exit"):
        pass_speed(s, 80.0, 50.0)


def test_candidate_profiles_match() -> None:
    for c in plan_candidates(four_way_junction(n_lanes=2), "left"):
        np.testing.assert_allclose(c.v_pass, pass_speed(c.s, c.s_stop_line, c.s_exit))
        np.testing.assert_allclose(c.v_stop, stop_speed(c.s, c.s_stop_line, c.s_exit))
        assert np.all(c.v_pass[c.segment == "curve"] == pytest.approx(inside_speed()))
        assert np.all(c.v_stop[c.segment == "curve"] == 0.0)
        assert np.all(c.v_stop[c.segment == "exit"] == pytest.approx(V0))
        assert c.v_stop[0] == pytest.approx(V0)  # 50 m entrance: starts at cruise speed
