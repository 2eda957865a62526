"""The ego's model f_ego (SPEC §5, paper Sec. IV-D): the semi-implicit dynamic bicycle of Ge et al.

State ``[p_x, p_y, v_x, v_y, φ, ω, δ, a]`` (world frame position [m], body-frame longitudinal and
lateral speed [m/s], heading [rad], yaw rate [rad/s], front wheel angle [rad], acceleration [m/s²]);
action ``[Δδ, Δa]`` (steering rate [rad/s], jerk [m/s³]). Δt = 0.1 s.

The update is the paper's equation, term by term::

    p_x' = p_x + Δt (v_x cos φ − v_y sin φ)
    p_y' = p_y + Δt (v_x sin φ + v_y cos φ)
    v_x' = v_x + Δt (a + v_y ω)
    v_y' = [m v_x v_y + Δt ((L_f k_f − L_r k_r) ω − k_f δ v_x − m v_x² ω)] / [m v_x − Δt (k_f + k_r)]
    φ'   = φ + Δt ω
    ω'   = [−I_z ω v_x − Δt ((L_f k_f − L_r k_r) v_y − L_f k_f δ v_x)] / [Δt (L_f² k_f + L_r² k_r) − I_z v_x]
    δ'   = δ + Δt Δδ
    a'   = a + Δt Δa

with k_f = k_r < 0: for v_x ≥ 0 the first denominator is ≥ −Δt (k_f + k_r) > 0 and the second
≤ Δt (L_f² k_f + L_r² k_r) < 0, so neither vanishes and the model stays finite at standstill.

Limits (SPEC §4): the action is clipped to |Δδ| ≤ 0.4 rad/s, |Δa| ≤ 4.5 m/s³; δ' and a' of the next
state to |δ| ≤ 0.4 rad and a ∈ [−3.0, 1.5] m/s². **(choice)** v_x' is clipped at 0: the car has no
reverse gear, so braking (a < 0) at standstill must hold it, not drive it backwards; this also keeps
v_x in the range where the denominators above are bounded away from zero.

One definition serves numpy arrays and torch tensors (batched over leading dimensions); with
tensors every operation is differentiable (the clips pass gradient inside their range).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from crossroads.arrays import ScalarOps, is_torch, ops
from crossroads.constants import (
    ACCEL_MAX,
    ACCEL_MIN,
    DT_S,
    I_Z,
    JERK_MAX,
    K_F,
    K_R,
    L_F,
    L_R,
    MASS_KG,
    STEER_MAX,
    STEER_RATE_MAX,
)


def clip_action(action: Any) -> Any:
    """``[Δδ, Δa]`` clipped to |Δδ| ≤ 0.4 rad/s and |Δa| ≤ 4.5 m/s³ (same backend and shape)."""
    xp = ops(action)
    action = xp.asarray(action, like=action)
    return xp.stack([xp.clip(action[..., 0], -STEER_RATE_MAX, STEER_RATE_MAX),
                     xp.clip(action[..., 1], -JERK_MAX, JERK_MAX)], axis=-1)


def ego_step(state: Any, action: Any, dt: float = DT_S) -> Any:
    """One step of f_ego: ``state[..., 8]``, ``action[..., 2]`` → next ``state[..., 8]``.

    The action is clipped first (see :func:`clip_action`); δ and a of the next state are clipped to
    their ranges and v_x is kept ≥ 0 (module docstring). Numpy in, numpy out; tensor in, tensor out.
    A single numpy state (shape (8,)) is stepped on Python floats (same formulas, :func:`_f_ego`).
    """
    if isinstance(state, np.ndarray) and state.shape == (8,) and not is_torch(action):
        u = np.asarray(action, dtype=np.float64)
        return np.array(ego_step_floats(state.tolist(), float(u[0]), float(u[1]), dt), dtype=state.dtype
                        if state.dtype.kind == "f" else np.float64)
    xp = ops(state, action)
    state = xp.asarray(state, like=state)
    action = xp.asarray(action, like=state)
    u = clip_action(action)
    parts = _f_ego(xp, *(state[..., i] for i in range(8)), u[..., 0], u[..., 1], dt)
    return xp.stack(list(parts), axis=-1)


def ego_step_floats(state: Sequence[float], d_delta: float, d_acc: float, dt: float = DT_S) -> tuple[float, ...]:
    """:func:`ego_step` of one state (8 Python floats) and one action [Δδ, Δa], on Python floats: the
    same numbers as ``ego_step(np.array(state), np.array([d_delta, d_acc]))``, for loops that step one
    ego many times (the safety shield's backups: 80 steps a decision)."""
    return _f_ego(ScalarOps, *state, ScalarOps.clip(d_delta, -STEER_RATE_MAX, STEER_RATE_MAX),
                  ScalarOps.clip(d_acc, -JERK_MAX, JERK_MAX), dt)


def _f_ego(xp: Any, px: Any, py: Any, vx: Any, vy: Any, phi: Any, omega: Any, delta: Any, acc: Any,
           d_delta: Any, d_acc: Any, dt: float) -> tuple[Any, ...]:
    """The paper's f_ego, term by term, on any namespace (numpy, torch or Python floats)."""
    cos_phi, sin_phi = xp.cos(phi), xp.sin(phi)
    lk = L_F * K_F - L_R * K_R

    px_next = px + dt * (vx * cos_phi - vy * sin_phi)
    py_next = py + dt * (vx * sin_phi + vy * cos_phi)
    vx_next = vx + dt * (acc + vy * omega)
    vy_next = (MASS_KG * vx * vy + dt * (lk * omega - K_F * delta * vx - MASS_KG * vx * vx * omega)) / (
        MASS_KG * vx - dt * (K_F + K_R)
    )
    phi_next = phi + dt * omega
    omega_next = (-I_Z * omega * vx - dt * (lk * vy - L_F * K_F * delta * vx)) / (
        dt * (L_F * L_F * K_F + L_R * L_R * K_R) - I_Z * vx
    )
    delta_next = xp.clip(delta + dt * d_delta, -STEER_MAX, STEER_MAX)
    acc_next = xp.clip(acc + dt * d_acc, ACCEL_MIN, ACCEL_MAX)
    vx_next = xp.clip(vx_next, 0.0, None)
    return px_next, py_next, vx_next, vy_next, phi_next, omega_next, delta_next, acc_next


def braking_distance_m(speed: Any, accel: Any = 0.0, max_steps: int = 400) -> np.ndarray:
    """[m] f_ego travels on a straight road from ``speed`` [m/s] and acceleration ``accel`` [m/s²]
    under full braking (Δa = −4.5 m/s³ until a = −3 m/s², then held) until it stands; broadcast over
    arrays. Stepped through :func:`ego_step` itself, so it is the distance the model's own
    discretisation needs, not the continuous formula's (p moves with the old v and v with the old a,
    so it travels up to two steps' distance more)."""
    speed, accel = np.broadcast_arrays(np.asarray(speed, dtype=np.float64), np.asarray(accel, dtype=np.float64))
    state = np.zeros(speed.shape + (8,))
    state[..., 2], state[..., 7] = speed, np.clip(accel, ACCEL_MIN, ACCEL_MAX)
    brake = np.broadcast_to(np.array([0.0, -JERK_MAX]), speed.shape + (2,))
    for _ in range(max_steps):  # 8.33 m/s stops in ~35 steps; the cap only guards absurd inputs
        if not np.any(state[..., 2] > 0.0):
            break
        state = np.where((state[..., 2] > 0.0)[..., None], ego_step(state, brake), state)
    return state[..., 0]
