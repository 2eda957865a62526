"""Synthetic states with a car standing ahead of the ego on its path (rl.augment)."""

from __future__ import annotations

import numpy as np
import pytest

from crossroads.constants import EGO_LENGTH_M
from crossroads.idc.state import KIND_ROWS, N_OTHERS, pad_participant
from crossroads.intersections import catalogue
from crossroads.rl.augment import CAR_LENGTH_M, standing_car_copies, with_standing_car
from crossroads.rl.buffer import Samples
from crossroads.sim.config import WorldConfig
from crossroads.sim.ego import braking_distance_m
from crossroads.sim.traffic import NO_TRAFFIC
from crossroads.sim.world import World


@pytest.fixture(scope="module")
def straight_path():
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="straight", demand=NO_TRAFFIC, warmup_s=1.0)
    with World(config) as world:
        return world.candidates[0]


def _samples(path, n: int, real_vehicle_ahead_m: float | None = None) -> Samples:
    """``n`` states of an ego on ``path`` (10 m apart), others padded; optionally one real vehicle."""
    ego, others = [], []
    for k in range(n):
        x, y, h, _ = path.reference_at(5.0 + 10.0 * k)
        e = np.array([x, y, 5.0, 0.0, h, 0.0, 0.0, 0.0])
        o = np.tile(pad_participant(e), (N_OTHERS, 1))
        if real_vehicle_ahead_m is not None:
            vx, vy, vh, _ = path.reference_at(5.0 + 10.0 * k + real_vehicle_ahead_m)
            o[0] = [vx, vy, 6.0, vh, 4.5, 1.9]
        o[KIND_ROWS["pedestrian"].start] = [x + 3.0, y + 3.0, 1.0, 0.0, 0.5, 0.5]
        ego.append(e)
        others.append(o)
    return Samples(np.asarray(ego, np.float32), np.asarray(others, np.float32),
                   np.full((n, N_OTHERS), 0.01, np.float32), np.full(n, 3, np.int64), np.zeros(n, bool))


def test_the_car_stands_on_the_path_at_the_gap_and_the_rest_is_kept(straight_path) -> None:
    samples = _samples(straight_path, 2, real_vehicle_ahead_m=40.0)
    before = samples.others.copy()
    copy = with_standing_car(samples, 1, straight_path, 7.0)
    np.testing.assert_array_equal(samples.others, before)  # the source is not changed
    ego, vehicles = copy.ego[0], copy.others[0, KIND_ROWS["vehicle"]]
    car = vehicles[0]  # closer than the real vehicle 40 m ahead: sorted first
    assert car[2] == 0.0 and car[4] == CAR_LENGTH_M
    assert np.hypot(car[0] - ego[0], car[1] - ego[1]) == pytest.approx(7.0 + 0.5 * (EGO_LENGTH_M + CAR_LENGTH_M), abs=0.05)
    assert straight_path.project(float(car[0]), float(car[1])).lateral_m == pytest.approx(0.0, abs=0.05)
    assert copy.kappa[0, 0] == 0.0
    np.testing.assert_array_equal(vehicles[1], samples.others[1, 0])  # the real vehicle, one slot on
    distances = np.hypot(vehicles[:, 0] - ego[0], vehicles[:, 1] - ego[1])
    assert np.all(np.diff(distances) >= 0.0)
    np.testing.assert_array_equal(copy.others[0, 8:], samples.others[1, 8:])  # cyclists, pedestrians
    np.testing.assert_array_equal(copy.ego[0], samples.ego[1])
    assert copy.path[0] == 3 and not copy.stop[0]


def test_copies_are_a_share_and_repeatable(straight_path) -> None:
    samples = _samples(straight_path, 6)
    assert len(standing_car_copies(samples, straight_path, 0.0, (1.0, 2.0), np.random.default_rng(0)).ego) == 0
    every = standing_car_copies(samples, straight_path, 1.0, (1.0, 30.0), np.random.default_rng(0))
    assert len(every.ego) == 6
    again = standing_car_copies(samples, straight_path, 1.0, (1.0, 30.0), np.random.default_rng(0))
    np.testing.assert_array_equal(every.others, again.others)
    gaps = np.hypot(*(every.others[:, 0, :2] - every.ego[:, :2]).T) - 0.5 * (EGO_LENGTH_M + CAR_LENGTH_M)
    assert np.all((gaps > 0.9) & (gaps < 30.1))


def test_stoppable_copies_stand_beyond_the_braking_distance(straight_path) -> None:
    samples = _samples(straight_path, 6)  # every ego at 5 m/s, a = 0
    samples.ego[::2, 2] = 8.0
    samples.ego[1, 7] = -3.0  # already braking: needs less room
    bumper = standing_car_copies(samples, straight_path, 1.0, (1.0, 2.0), np.random.default_rng(3))
    beyond = standing_car_copies(samples, straight_path, 1.0, (1.0, 2.0), np.random.default_rng(3), stoppable=True)
    half = 0.5 * (EGO_LENGTH_M + CAR_LENGTH_M)

    def gaps(copies: Samples) -> np.ndarray:
        return np.hypot(*(copies.others[:, 0, :2] - copies.ego[:, :2]).T) - half

    needed = braking_distance_m(samples.ego[:, 2], samples.ego[:, 7])
    assert needed[0] == pytest.approx(14.09, abs=0.05) and needed[1] < braking_distance_m(5.0)
    np.testing.assert_allclose(gaps(beyond), gaps(bumper) + needed, atol=0.05)  # same draws, moved on
    assert np.all(gaps(beyond) > needed + 0.9)
