"""Perception noise (SPEC §3): Gaussian with the paper's (mean, std) per participant type."""

from __future__ import annotations

import numpy as np
import pytest

from crossroads.constants import PERCEPTION_NOISE
from crossroads.perception.noise import FIELDS, KINDS, MIN_SIZE_M, add_noise, add_noise_unchecked


def base(n: int) -> np.ndarray:
    return np.tile([10.0, -5.0, 8.0, 0.5, 4.5, 1.8], (n, 1))


@pytest.mark.parametrize("kind", ["vehicle", "cyclist", "pedestrian"])
def test_statistics_match_the_table(kind: str) -> None:
    n = 200_000
    obs = base(n)
    noisy = add_noise(obs, np.array([kind] * n), np.random.default_rng(7))
    err = noisy - obs
    for k, field in enumerate(FIELDS):
        mean, std = PERCEPTION_NOISE[kind][field]
        assert err[:, k].mean() == pytest.approx(mean, abs=4 * std / np.sqrt(n) + 1e-12), field
        assert err[:, k].std() == pytest.approx(std, rel=0.02), field


def test_seeded_and_per_row_kinds() -> None:
    obs = base(6)
    kinds = np.array(["vehicle", "cyclist", "pedestrian"] * 2)
    a = add_noise(obs, kinds, np.random.default_rng(3))
    b = add_noise(obs, kinds, np.random.default_rng(3))
    c = add_noise(obs, kinds, np.random.default_rng(4))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    assert a.shape == (6, 6) and not np.shares_memory(a, obs)
    np.testing.assert_array_equal(obs, base(6))  # input untouched
    empty = add_noise(np.zeros((0, 6)), np.array([], dtype=str), np.random.default_rng(0))
    assert empty.shape == (0, 6)


def test_bounds() -> None:
    obs = np.tile([0.0, 0.0, 0.0, np.pi - 1e-3, 0.1, 0.1], (5000, 1))
    noisy = add_noise(obs, np.array(["pedestrian"] * 5000), np.random.default_rng(0))
    assert (noisy[:, 2] >= 0).all() and (noisy[:, 4:] >= MIN_SIZE_M).all()
    assert (noisy[:, 3] >= -np.pi).all() and (noisy[:, 3] < np.pi).all()


def test_errors() -> None:
    with pytest.raises(ValueError, match="unknown participant kind"):
        add_noise(base(1), np.array(["tram"]), np.random.default_rng(0))
    with pytest.raises(ValueError):
        add_noise(np.zeros((2, 5)), np.array(["vehicle"] * 2), np.random.default_rng(0))
    with pytest.raises(ValueError):
        add_noise(base(2), np.array(["vehicle"]), np.random.default_rng(0))


def test_unchecked_is_the_same_noise() -> None:
    rng = np.random.default_rng(1)
    obs = np.column_stack([rng.uniform(-50, 50, (300, 2)), rng.uniform(0, 0.3, 300), rng.uniform(-3.2, 3.2, 300),
                           rng.uniform(0.05, 5, (300, 2))])
    codes = rng.integers(0, 3, 300).astype(np.int8)
    names = np.array(KINDS)[codes]
    # the formula as first written: one expression, then the clamps and the wrap on copies
    z = np.random.default_rng(9).standard_normal(obs.shape)
    mean = np.array([[PERCEPTION_NOISE[k][f][0] for f in FIELDS] for k in KINDS])[codes]
    std = np.array([[PERCEPTION_NOISE[k][f][1] for f in FIELDS] for k in KINDS])[codes]
    expected = obs + mean + std * z
    expected[:, 2] = np.maximum(expected[:, 2], 0.0)
    expected[:, 3] = np.mod(expected[:, 3] + np.pi, 2.0 * np.pi) - np.pi
    expected[:, 4:6] = np.maximum(expected[:, 4:6], MIN_SIZE_M)
    for got in (add_noise(obs, names, np.random.default_rng(9)), add_noise(obs, codes, np.random.default_rng(9)),
                add_noise_unchecked(obs, codes, np.random.default_rng(9))):
        assert got.tobytes() == expected.tobytes()
