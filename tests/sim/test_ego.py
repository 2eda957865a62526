"""f_ego (SPEC §5): the paper's semi-implicit dynamic bicycle model, numpy and torch."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from crossroads.constants import (
    ACCEL_MAX, ACCEL_MIN, DT_S, I_Z, JERK_MAX, K_F, K_R, L_F, L_R, MASS_KG, STEER_MAX, STEER_RATE_MAX,
)
from crossroads.sim.ego import braking_distance_m, clip_action, ego_step, ego_step_floats


def paper_step(s, u, dt=DT_S):
    """The paper's equation written out with scalars, for one unclipped step."""
    px, py, vx, vy, phi, w, d, a = s
    dd, da = u
    return np.array([
        px + dt * (vx * math.cos(phi) - vy * math.sin(phi)),
        py + dt * (vx * math.sin(phi) + vy * math.cos(phi)),
        vx + dt * (a + vy * w),
        (MASS_KG * vx * vy + dt * ((L_F * K_F - L_R * K_R) * w - K_F * d * vx - MASS_KG * vx**2 * w))
        / (MASS_KG * vx - dt * (K_F + K_R)),
        phi + dt * w,
        (-I_Z * w * vx - dt * ((L_F * K_F - L_R * K_R) * vy - L_F * K_F * d * vx))
        / (dt * (L_F**2 * K_F + L_R**2 * K_R) - I_Z * vx),
        d + dt * dd,
        a + dt * da,
    ])


def test_one_step_is_the_papers_equation() -> None:
    s = np.array([3.0, -2.0, 7.0, 0.3, 0.7, 0.12, 0.05, 0.4])
    u = np.array([0.2, -1.0])
    np.testing.assert_allclose(ego_step(s, u), paper_step(s, u), rtol=1e-12, atol=1e-12)


def test_finite_at_standstill_over_1000_steps() -> None:
    rng = np.random.default_rng(0)
    s = np.zeros(8)
    for _ in range(1000):
        s = ego_step(s, rng.uniform([-0.4, -4.5], [0.4, 4.5]) * rng.choice([0.0, 1.0]))
        assert np.all(np.isfinite(s))
        assert s[2] >= 0.0
    # braking at standstill holds the car
    s = np.zeros(8)
    s[7] = ACCEL_MIN
    for _ in range(100):
        s = ego_step(s, [0.0, -JERK_MAX])
    assert np.all(np.isfinite(s)) and s[2] == 0.0 and abs(s[0]) < 1e-12 and abs(s[1]) < 1e-12


def test_accelerates_straight() -> None:
    s = np.zeros(8)
    s[7] = 1.0
    for _ in range(50):
        s = ego_step(s, [0.0, 0.0])
    assert s[2] == pytest.approx(50 * DT_S * 1.0, abs=1e-9)  # v = Σ Δt·a
    assert s[0] > 10.0 and abs(s[1]) < 1e-12 and s[4] == 0.0 and s[3] == 0.0


def test_positive_steering_turns_left() -> None:
    s = np.array([0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 0.1, 0.0])
    for _ in range(30):
        s = ego_step(s, [0.0, 0.0])
    assert s[4] > 0.0 and s[5] > 0.0 and s[1] > 0.0
    # steady yaw rate close to the kinematic v·δ/(L_f + L_r) at this moderate speed
    assert s[5] == pytest.approx(s[2] * 0.1 / (L_F + L_R), rel=0.15)
    s[6] = -0.1
    s[5] = 0.0
    for _ in range(30):
        s = ego_step(s, [0.0, 0.0])
    assert s[5] < 0.0


def test_limits() -> None:
    np.testing.assert_allclose(clip_action([1.0, -10.0]), [STEER_RATE_MAX, -JERK_MAX])
    np.testing.assert_allclose(clip_action([[-1.0, 10.0], [0.1, 0.2]]), [[-STEER_RATE_MAX, JERK_MAX], [0.1, 0.2]])
    s = np.array([0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    nxt = ego_step(s, [5.0, 50.0])
    assert nxt[6] == pytest.approx(DT_S * STEER_RATE_MAX) and nxt[7] == pytest.approx(DT_S * JERK_MAX)
    s[6], s[7] = STEER_MAX, ACCEL_MAX
    nxt = ego_step(s, [0.4, 4.5])
    assert nxt[6] == STEER_MAX and nxt[7] == ACCEL_MAX
    s[6], s[7] = -STEER_MAX, ACCEL_MIN
    nxt = ego_step(s, [-0.4, -4.5])
    assert nxt[6] == -STEER_MAX and nxt[7] == ACCEL_MIN


def random_batch(seed: int = 1):
    rng = np.random.default_rng(seed)
    s = rng.uniform([-50, -50, 0, -1, -3, -0.5, -0.4, -3], [50, 50, 15, 1, 3, 0.5, 0.4, 1.5], size=(5, 3, 8))
    u = rng.uniform(-5, 5, size=(5, 3, 2))
    return s, u


def test_numpy_equals_torch_batched() -> None:
    s, u = random_batch()
    out_np = ego_step(s, u)
    out_t = ego_step(torch.tensor(s), torch.tensor(u))
    assert isinstance(out_t, torch.Tensor) and out_t.dtype == torch.float64 and out_np.shape == (5, 3, 8)
    np.testing.assert_allclose(out_t.numpy(), out_np, rtol=1e-9, atol=1e-9)
    for k in range(5):  # batched == one by one
        np.testing.assert_allclose(out_np[k, 1], ego_step(s[k, 1], u[k, 1]), atol=1e-12)


def test_gradients_flow() -> None:
    s0 = torch.tensor([0.0, 0.0, 5.0, 0.0, 0.3, 0.0, 0.0, 0.0], dtype=torch.float64, requires_grad=True)
    u = torch.tensor([[0.1, 0.5]] * 10, dtype=torch.float64, requires_grad=True)
    s = s0
    for k in range(10):
        s = ego_step(s, u[k])
    (s[1] + s[4] + s[2]).backward()
    assert torch.isfinite(u.grad).all() and u.grad.abs().sum() > 0
    assert torch.isfinite(s0.grad).all() and s0.grad[2] > 0
    # at standstill too
    z = torch.zeros(8, dtype=torch.float64, requires_grad=True)
    ego_step(z, torch.tensor([0.1, 1.0], dtype=torch.float64)).sum().backward()
    assert torch.isfinite(z.grad).all()


def test_single_state_fast_path_equals_the_batched_and_torch_paths() -> None:
    """One (8,) state is stepped on Python floats: the same numbers as numpy batches and torch."""
    import torch

    from crossroads.sim.ego import ego_step

    rng = np.random.default_rng(11)
    for _ in range(300):
        state = rng.uniform([-50, -50, 0, -1, -3, -1, -0.5, -3.5], [50, 50, 12, 1, 3, 1, 0.5, 2.0])
        action = rng.uniform(-6.0, 6.0, 2)  # beyond the limits too: clipping must agree
        single = ego_step(state, action)
        assert single.shape == (8,) and single.dtype == np.float64
        np.testing.assert_allclose(single, ego_step(state[None], action[None])[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(single, ego_step(torch.tensor(state), torch.tensor(action)).numpy(),
                                   rtol=0, atol=1e-12)


def test_float_steps_are_the_single_state_path_exactly() -> None:
    """ego_step_floats (the shield's backups) gives ego_step's numbers bit for bit, step after step."""
    rng = np.random.default_rng(12)
    for _ in range(50):
        state = rng.uniform([-50, -50, 0, -1, -3, -1, -0.5, -3.5], [50, 50, 12, 1, 3, 1, 0.5, 2.0])
        floats = tuple(state.tolist())
        for action in rng.uniform(-6.0, 6.0, (40, 2)):
            state = ego_step(state, action)
            floats = ego_step_floats(floats, float(action[0]), float(action[1]))
            assert state.tolist() == list(floats)


def test_braking_distance_follows_f_ego() -> None:
    assert braking_distance_m(0.0) == 0.0
    distances = braking_distance_m(np.array([2.0, 4.0, 6.0, 8.0]))
    assert np.all(np.diff(distances) > 0)
    # continuous: the jerk ramp to −3 m/s² (0.67 s), then v²/6 from the speed left; discrete f_ego
    # lags a step twice (p moves with the old v, v with the old a), so it travels up to 2 steps more
    v0, ramp = 8.0, 3.0 / 4.5
    v1 = v0 - 0.5 * 4.5 * ramp**2
    continuous = v0 * ramp - 4.5 * ramp**3 / 6 + v1**2 / 6.0
    assert continuous < distances[3] < continuous + 2 * 0.1 * v0
    assert braking_distance_m(8.0, -3.0) < distances[3] < braking_distance_m(8.0, 1.5)
