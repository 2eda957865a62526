"""f_other (SPEC §5) and the route curvature 1/R."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from crossroads.constants import DT_S
from crossroads.sim.other import other_braking_step, other_step, route_curvature


def test_straight_motion_without_noise() -> None:
    o = np.array([1.0, 2.0, 10.0, math.pi / 2, 4.5, 1.8])
    n = other_step(o, 0.0)
    np.testing.assert_allclose(n, [1.0, 2.0 + DT_S * 10.0, 10.0, math.pi / 2, 4.5, 1.8], atol=1e-12)


def test_turning_and_xi() -> None:
    o = np.array([[0.0, 0.0, 5.0, 0.0, 4.0, 2.0], [1.0, 1.0, 2.0, 1.0, 0.5, 0.5]])
    kappa = np.array([0.1, -0.2])
    xi = np.array([0.1, -0.2, 0.05, 0.01])
    n = other_step(o, kappa, xi)
    assert n[0, 3] == pytest.approx(DT_S * 5.0 * 0.1 + 0.01)
    assert n[1, 3] == pytest.approx(1.0 - DT_S * 2.0 * 0.2 + 0.01)
    assert n[0, 0] == pytest.approx(DT_S * 5.0 + 0.1) and n[0, 1] == pytest.approx(-0.2)
    assert n[1, 2] == pytest.approx(2.05)
    np.testing.assert_array_equal(n[:, 4:], o[:, 4:])


def test_numpy_equals_torch_and_gradients() -> None:
    rng = np.random.default_rng(3)
    o = rng.uniform(-10, 10, size=(7, 16, 6))
    k = rng.uniform(-0.1, 0.1, size=(7, 16))
    xi = rng.uniform(-0.8, 0.8, size=(7, 16, 4))
    out_np = other_step(o, k, xi)
    xi_t = torch.tensor(xi, requires_grad=True)
    out_t = other_step(torch.tensor(o), torch.tensor(k), xi_t)
    np.testing.assert_allclose(out_t.detach().numpy(), out_np, rtol=1e-9, atol=1e-9)
    out_t[..., :4].sum().backward()
    np.testing.assert_allclose(xi_t.grad.numpy(), np.ones_like(xi))


def arc(radius: float, ccw: bool, spacing: float = 0.5) -> np.ndarray:
    n = int(radius * math.pi / 2 / spacing) + 1
    a = np.linspace(0.0, math.pi / 2, n)
    if not ccw:
        return np.column_stack([radius * np.sin(a), radius * np.cos(a)])
    return np.column_stack([radius * np.cos(a), radius * np.sin(a)])


def test_route_curvature_of_arcs_and_lines() -> None:
    left = arc(10.0, ccw=True)
    assert route_curvature(left, 10.0 * math.cos(0.7), 10.0 * math.sin(0.7)) == pytest.approx(0.1, rel=0.02)
    right = arc(20.0, ccw=False)
    assert route_curvature(right, 20.0 * math.sin(0.7), 20.0 * math.cos(0.7)) == pytest.approx(-0.05, rel=0.02)
    line = np.column_stack([np.linspace(0, 50, 101), np.linspace(0, 20, 101)])
    assert route_curvature(line, 10.0, 3.0) == pytest.approx(0.0, abs=1e-9)
    assert route_curvature(np.array([[0.0, 0.0], [10.0, 0.0]]), 3.0, 1.0) == 0.0
    # a sparse SUMO-like shape: a 90° left turn of radius 8 in 5 vertices
    sparse = arc(8.0, ccw=True, spacing=3.0)
    assert route_curvature(sparse, 0.0, 8.0) == pytest.approx(1 / 8.0, rel=0.1)
    # repeated vertices are harmless
    assert route_curvature(np.vstack([left[:5], left[4:]]), 10.0, 0.0) == pytest.approx(0.1, rel=0.05)


def test_braking_step_stops_each_participant_at_its_stopping_distance_numpy_and_torch() -> None:
    """v²/(2·4.5) ahead (to within one step's travel, the recursion moves with the old speed), on
    its curve, and then stands; torch gives the same numbers."""
    others = np.array([[0.0, 0.0, 9.0, 0.0, 4.8, 1.8], [5.0, 5.0, 0.0, 1.0, 0.5, 0.5]])
    kappa = np.array([0.0, 0.02])
    state, state_t = others, torch.as_tensor(others)
    for _ in range(40):
        state = other_braking_step(state, kappa, 4.5)
        state_t = other_braking_step(state_t, torch.as_tensor(kappa), 4.5)
    np.testing.assert_allclose(state_t.numpy(), state, atol=1e-9)
    assert state[0, 2] == 0.0 and state[1, 2] == 0.0
    assert 9.0**2 / 9.0 <= state[0, 0] <= 9.0**2 / 9.0 + 9.0 * DT_S
    np.testing.assert_array_equal(state[1], others[1])  # standing: nowhere to go
