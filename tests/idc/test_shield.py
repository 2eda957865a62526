"""The safety shield (idc.shield): its predictions, its backups and when it brakes."""

from __future__ import annotations

import numpy as np
import pytest

from crossroads.constants import DT_S, JERK_MAX, OTHER_DECEL_MPS2, STOP_LINE_GAP_M
from crossroads.idc.constraints import EGO_CIRCLE_OFFSET_M, EGO_RADIUS_M, deepest_by_slot, safety_constraints
from crossroads.idc.shield import (
    SHIELD_CLEARANCE_M,
    SHIELD_RELEASE_MARGIN_M,
    EXIT_ALIGNED_RAD,
    HOLD_WHEEL,
    _deepest_by_slot,
    backups,
    braking_action,
    followers,
    go_is_worse,
    predicted_others,
    shield_action,
)
from crossroads.idc.state import N_OTHERS, pad_participant
from crossroads.sim.ego import braking_distance_m
from crossroads.sim.other import other_braking_step, other_step

CAR_L, CAR_W = 5.0, 1.8
EGO = np.array([0.0, 0.0, 8.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # 8 m/s due east, a = 0
ACCELERATE = np.array([0.0, JERK_MAX])


def _scene(*cars: tuple[float, float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """x_other with the given cars (x, y, v, φ) in the first vehicle slots, the rest padded; κ = 0."""
    others = np.tile(pad_participant(EGO), (N_OTHERS, 1))
    for k, (x, y, v, phi) in enumerate(cars):
        others[k] = [x, y, v, phi, CAR_L, CAR_W]
    return others, np.zeros(N_OTHERS)


def test_the_predictions_are_f_other_stepped() -> None:
    rng = np.random.default_rng(1)
    others = np.column_stack([rng.uniform(-30, 30, N_OTHERS), rng.uniform(-30, 30, N_OTHERS), rng.uniform(0, 8, N_OTHERS),
                              rng.uniform(-3, 3, N_OTHERS), np.full(N_OTHERS, 4.8), np.full(N_OTHERS, 1.8)])
    kappa = rng.uniform(-0.1, 0.1, N_OTHERS)
    got = predicted_others(others, kappa, 40)
    keep = brake = others
    for i in range(40):
        keep = other_step(keep, kappa)
        brake = other_braking_step(brake, kappa, OTHER_DECEL_MPS2)
        np.testing.assert_allclose(got[0, i], keep, atol=1e-9)
        np.testing.assert_allclose(got[1, i], brake, atol=1e-9)
    assert np.all(got[1, -1, :, 2] == 0.0)  # 8 m/s at 4.5 m/s² stands within 2 s


def _brake_overlap(gap_centre_m: float) -> float:
    return backups(EGO, *_scene((gap_centre_m, 0.0, 0.0, 0.0)), ACCELERATE).brake_overlap_m


def test_braking_now_stops_where_full_braking_stops() -> None:
    # the nearest standing car braking-now keeps clear of: f_ego's braking distance plus the
    # circles' reach (ego front circle + car rear circle + the clearance), found by bisection
    lo, hi = 5.0, 40.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _brake_overlap(mid) > 0.0 else (lo, mid)
    reach = EGO_CIRCLE_OFFSET_M + EGO_RADIUS_M + (CAR_L - CAR_W) / 2 + CAR_W / 2 + SHIELD_CLEARANCE_M
    assert hi == pytest.approx(float(braking_distance_m(8.0, 0.0)) + reach, abs=0.05)


def test_it_brakes_when_only_braking_now_keeps_clear_and_not_otherwise() -> None:
    stop_now = float(braking_distance_m(8.0, 0.0))
    reach = EGO_CIRCLE_OFFSET_M + EGO_RADIUS_M + (CAR_L - CAR_W) / 2 + CAR_W / 2 + SHIELD_CLEARANCE_M
    tight = _scene((stop_now + reach + 0.1, 0.0, 0.0, 0.0))
    verdict = shield_action(EGO, *tight, ACCELERATE)
    assert verdict.backups.go_overlap_m > 0.0 >= verdict.backups.brake_overlap_m
    assert verdict.backups.brake_overlap_m <= 0.0
    assert verdict.braking and np.array_equal(verdict.action, HOLD_WHEEL)
    far = shield_action(EGO, *_scene((60.0, 0.0, 0.0, 0.0)), ACCELERATE)
    assert not far.braking and np.array_equal(far.action, ACCELERATE)


def test_cars_in_the_next_lanes_and_followers_do_not_make_it_brake() -> None:
    beside = _scene((10.0, 3.5, 0.0, 0.0), (25.0, -3.5, 0.0, 0.0))  # a standing queue one lane over
    assert not shield_action(EGO, *beside, ACCELERATE).braking
    follower = _scene((-25.0, 0.0, 8.0, 0.0))  # 25 m behind at 8 m/s: it brakes when the ego does
    assert followers(EGO, follower[0])[0]
    kept = backups(EGO, *follower, ACCELERATE)
    assert kept.go_overlap_m <= 0.0 and kept.brake_overlap_m <= 0.0
    oncoming = _scene((-25.0, 0.0, 8.0, np.pi))  # behind but driving away the other way: no follower
    assert not followers(EGO, oncoming[0])[0]


def test_a_car_driving_away_ahead_is_no_reason_to_brake_but_one_braking_ahead_is() -> None:
    assert not shield_action(EGO, *_scene((20.0, 0.0, 8.0, 0.0)), ACCELERATE).braking
    # 8 m/s, 14 m ahead (centres): if it brakes hard, the ego accelerating now cannot stop behind it
    assert shield_action(EGO, *_scene((14.0, 0.0, 8.0, 0.0)), ACCELERATE).braking


def test_standing_inside_the_clearance_already_is_no_reason_to_brake_for_ever() -> None:
    standing = EGO.copy()
    standing[2] = 0.0
    narrow = _scene((0.0, 2.8, 0.0, 0.0))  # a car alongside in a narrow neighbouring lane: inside the clearance
    hold = np.zeros(2)
    verdict = shield_action(standing, *narrow, hold)
    assert verdict.backups.go_overlap_m > 0.0 and not verdict.braking
    # creeping at the queued car 0.6 m ahead (bumpers) makes it worse: that it stops
    queued = _scene((0.5 * (4.8 + CAR_L) + 0.6, 0.0, 0.0, 0.0))
    assert shield_action(standing, *queued, np.array([0.0, JERK_MAX])).braking
    assert not shield_action(standing, *queued, np.array([0.0, -JERK_MAX])).braking


def test_a_line_that_holds_the_ego_is_a_place_to_stand_short_of() -> None:
    """In the stop mode of a red or yellow light the stop line is a standing obstacle: the backups
    must stand STOP_LINE_GAP_M short of it. *brake* travels f_ego's braking distance."""
    empty = _scene()
    stop_now = float(braking_distance_m(8.0, 0.0))
    line = stop_now + STOP_LINE_GAP_M + 0.1  # braking now stands 0.1 m behind the gap, accelerating first does not
    verdict = shield_action(EGO, *empty, ACCELERATE, line_m=line)
    assert verdict.backups.brake_past_line_m == pytest.approx(-0.1, abs=0.02)
    assert verdict.backups.go_past_line_m > 0.0
    assert verdict.braking and verdict.action[1] == -JERK_MAX
    assert not shield_action(EGO, *empty, ACCELERATE, line_m=stop_now + 10.0).braking
    assert not shield_action(EGO, *empty, ACCELERATE).braking  # no line: nothing ahead
    unheld = backups(EGO, *empty, ACCELERATE)
    assert unheld.go_past_line_m == -np.inf and unheld.brake_past_line_m == -np.inf


def test_standing_at_a_red_line_it_holds_the_ego_until_the_line_lets_go() -> None:
    standing = EGO.copy()
    standing[2] = 0.0
    at_line = STOP_LINE_GAP_M + 0.005  # standing at the gap: a step of Δa = 4.5 m/s³ then braking creeps 9 mm
    assert shield_action(standing, *_scene(), ACCELERATE, line_m=at_line).braking
    assert not shield_action(standing, *_scene(), np.array([0.0, -JERK_MAX]), line_m=at_line).braking
    assert not shield_action(standing, *_scene(), ACCELERATE, line_m=None).braking  # green: go


def test_too_late_to_stand_short_of_the_line_it_still_brakes_to_cross_less_far() -> None:
    line = 2.0  # 8 m/s, 2 m short: no backup stands before it, braking crosses least
    verdict = shield_action(EGO, *_scene(), ACCELERATE, line_m=line)
    assert verdict.backups.brake_past_line_m > 0.0
    assert verdict.braking


def _obstacles(go: list[float], brake: list[float]) -> np.ndarray:
    """(2, 17) per-obstacle intrusions: the given participants first, the rest far, no line."""
    out = np.full((2, N_OTHERS + 1), -5.0)
    out[:, -1] = -np.inf
    out[0, :len(go)], out[1, :len(brake)] = go, brake
    return out


def test_it_compares_the_backups_obstacle_by_obstacle() -> None:
    assert not go_is_worse(_obstacles([-0.2], [-0.3]))  # go is clear
    assert not go_is_worse(_obstacles([0.9], [0.9]))  # braking helps no one: the policy's action
    # a neighbour 0.9 m deep in both hides nothing: the car ahead gets 0.1 m deeper along go
    assert go_is_worse(_obstacles([0.9, 0.5], [0.9, 0.4]))
    # each backup worse for someone: the shallower deepest intrusion decides
    assert not go_is_worse(_obstacles([0.5, 0.2], [0.4, 0.8]))
    assert go_is_worse(_obstacles([0.9, 0.2], [0.4, 0.5]))
    # short of the stop line standing is safe from everyone but followers (predicted braking)
    assert go_is_worse(_obstacles([0.5, 0.2], [0.4, 0.8]), before_line=True)
    assert not go_is_worse(_obstacles([0.9], [0.9]), before_line=True)


def test_a_held_line_is_not_traded_against_a_participant() -> None:
    trade = _obstacles([2.09], [2.14])  # a turner predicted a little deeper if the ego stands
    trade[:, -1] = [0.03, 0.02]  # go ends 1 cm further past the held line's gap
    assert go_is_worse(trade)
    trade[:, -1] = [0.02, 0.02]
    assert not go_is_worse(trade)


def test_a_neighbour_inside_the_clearance_does_not_hide_the_car_ahead() -> None:
    standing = EGO.copy()
    standing[2] = 0.0
    gap = 0.5 * (4.8 + CAR_L) + 0.6  # bumpers 0.6 m apart
    scene = _scene((0.0, 2.0, 0.0, 0.0), (gap, 0.0, 0.0, 0.0))  # alongside, 0.1 m between the bodies
    b = backups(standing, *scene, ACCELERATE)
    assert b.by_obstacle[0, 0] > b.by_obstacle[0, 1] > 0.0  # the neighbour intrudes deepest, in both
    assert b.go_overlap_m == pytest.approx(b.brake_overlap_m, abs=1e-3)  # by the deepest alone: a tie
    assert shield_action(standing, *scene, ACCELERATE).braking


def test_after_braking_go_must_clear_by_the_release_margin() -> None:
    nearly = _obstacles([-0.2], [-0.25])  # go keeps the clearance by 0.2 m only
    assert not go_is_worse(nearly)
    assert go_is_worse(nearly, release_m=SHIELD_RELEASE_MARGIN_M)
    assert not go_is_worse(_obstacles([-0.4], [-0.45]), release_m=SHIELD_RELEASE_MARGIN_M)
    standing = EGO.copy()
    standing[2] = 0.0
    # the car ahead 0.1 m beyond the clearance of a standing ego (bumpers 1.1 m apart): one step of
    # Δa = +4.5 m/s³ then braking keeps clear by ~0.1 m, inside the release margin
    scene = _scene((0.5 * (4.8 + CAR_L) + SHIELD_CLEARANCE_M + 0.1, 0.0, 0.0, 0.0))
    assert not shield_action(standing, *scene, ACCELERATE).braking
    assert shield_action(standing, *scene, ACCELERATE, braked_last_step=True).braking


def test_braking_holds_the_wheel_it_was_checked_with() -> None:
    """The backups hold the wheel after their first step, so a braking step must too: a policy that
    steers back towards a car the held wheel would have passed (the nominal left turn's queue) is
    not followed while the shield brakes."""
    swerving = EGO.copy()
    swerving[6] = 0.1  # the wheel turned left
    steer_right_and_go = np.array([-0.4, JERK_MAX])
    stop_now = float(braking_distance_m(8.0, 0.0))
    scene = _scene((stop_now + 3.0, 0.0, 0.0, 0.0))  # too close for go, not for brake
    verdict = shield_action(swerving, *scene, steer_right_and_go)
    assert verdict.braking
    assert np.array_equal(verdict.action, HOLD_WHEEL)  # not the policy's −0.4 rad/s
    assert HOLD_WHEEL[0] == 0.0 and HOLD_WHEEL[1] == -JERK_MAX
    # *brake* is what the command drives: its first step is HOLD_WHEEL's, so the next step's *go*
    # (that command, then braking) retraces it
    again = backups(swerving, *scene, HOLD_WHEEL)
    np.testing.assert_allclose(again.by_obstacle[0], again.by_obstacle[1])


def test_at_the_end_of_its_turn_braking_turns_the_wheel_back_to_straight() -> None:
    """Mid-turn the shield's braking holds the wheel (the ego stays on its arc); within 15° of its
    path's exit heading it turns the wheel back toward straight at the rate limit, so that the nose
    does not swing on into the opposite leg's lanes; the backups are rolled out the same way."""
    turning = EGO.copy()
    turning[6] = 0.1  # the wheel turned left, the ego heading east (0 rad)
    assert np.array_equal(braking_action(turning), HOLD_WHEEL)  # no path given: held
    assert np.array_equal(braking_action(turning, exit_heading=np.pi / 2), HOLD_WHEEL)  # 90° to go
    assert braking_action(turning, exit_heading=np.deg2rad(10.0)).tolist() == [-0.4, -JERK_MAX]
    turning[6] = 0.02
    np.testing.assert_allclose(braking_action(turning, exit_heading=-np.deg2rad(10.0)), [-0.2, -JERK_MAX])
    assert EXIT_ALIGNED_RAD == pytest.approx(np.deg2rad(15.0))
    # what the command drives when it brakes is the brake backup: go with that command retraces it
    scene = _scene((float(braking_distance_m(8.0, 0.0)) + 3.0, 0.0, 0.0, 0.0))
    command = braking_action(turning, exit_heading=0.0)
    again = backups(turning, *scene, command, exit_heading=0.0)
    np.testing.assert_allclose(again.by_obstacle[0], again.by_obstacle[1])


def _deepest_by_slot_of_states(ego: np.ndarray, egos: np.ndarray, others: np.ndarray, kappa: np.ndarray) -> np.ndarray:
    """The backups' per-slot intrusions (2, 16) computed plainly: a full state for every backup,
    step and future, through safety_constraints."""
    steps = len(egos)
    moved = predicted_others(others, kappa, steps)
    follows = followers(ego, others)
    moved[0][:, follows] = moved[1][:, follows]
    states = np.concatenate([np.broadcast_to(egos, (2, steps, 2, 8)), np.zeros((2, steps, 2, 4)),
                             np.broadcast_to(moved.reshape(2, steps, 1, -1), (2, steps, 2, moved[0, 0].size))], axis=-1)
    return deepest_by_slot(safety_constraints(states, SHIELD_CLEARANCE_M)).max(axis=(0, 1))



def test_the_backups_intrusions_are_safety_constraints_bit_for_bit() -> None:
    """The shield pairs each backup's ego with both futures of every participant without building a
    state for each pair (constraints.circle_gaps): the numbers of safety_constraints on those
    states, bit for bit, for random scenes (every kind of slot, pads, curving participants)."""
    rng = np.random.default_rng(6)
    steps = 40
    for _ in range(60):
        ego = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(0, 12), rng.normal(0, 0.3),
                        rng.uniform(-7, 7), rng.normal(0, 0.3), rng.uniform(-0.5, 0.5), rng.uniform(-3, 1.5)])
        others = np.tile(pad_participant(ego), (N_OTHERS, 1))
        real = rng.random(N_OTHERS) < 0.7
        n = int(real.sum())
        others[real] = np.column_stack([ego[:2] + rng.uniform(-30, 30, (n, 2)), rng.uniform(0, 12, n),
                                        rng.uniform(-7, 7, n), rng.uniform(0.3, 12, (n, 2))])
        kappa = np.where(real, rng.normal(0, 0.05, N_OTHERS), 0.0)
        egos = ego + np.cumsum(rng.normal(0, 0.3, (steps, 2, 8)), axis=0)  # two wandering backups
        expected = _deepest_by_slot_of_states(ego, egos, others, kappa)
        assert _deepest_by_slot(ego, egos, others, kappa, steps).tobytes() == expected.tobytes()


def _predicted_future_by_future(others: np.ndarray, kappa: np.ndarray, steps: int) -> np.ndarray:
    """predicted_others as first written: one future after the other."""
    n = np.arange(steps + 1)[:, None]
    out = np.empty((2, steps) + others.shape)
    for future, decel in enumerate((0.0, OTHER_DECEL_MPS2)):
        v = np.maximum(others[:, 2] - n * (decel * DT_S), 0.0) if decel else np.broadcast_to(others[:, 2], (steps + 1, len(others)))
        travelled = np.concatenate([np.zeros((1, len(others))), np.cumsum(DT_S * v[:-1], axis=0)])
        phi = others[:, 3] + travelled * kappa
        out[future, :, :, 0] = others[:, 0] + np.cumsum(DT_S * v[:-1] * np.cos(phi[:-1]), axis=0)
        out[future, :, :, 1] = others[:, 1] + np.cumsum(DT_S * v[:-1] * np.sin(phi[:-1]), axis=0)
        out[future, :, :, 2] = v[1:]
        out[future, :, :, 3] = phi[1:]
        out[future, :, :, 4:] = others[:, 4:]
    return out


def test_both_futures_at_once_are_each_future_alone_bit_for_bit() -> None:
    rng = np.random.default_rng(3)
    for _ in range(100):
        others = np.column_stack([rng.uniform(-60, 60, (N_OTHERS, 2)), rng.uniform(-0.5, 12, N_OTHERS),
                                  rng.uniform(-7, 7, N_OTHERS), rng.uniform(0.3, 12, (N_OTHERS, 2))])
        kappa = rng.normal(0.0, 0.1, N_OTHERS)
        steps = int(rng.integers(1, 60))
        assert predicted_others(others, kappa, steps).tobytes() == _predicted_future_by_future(others, kappa, steps).tobytes()
