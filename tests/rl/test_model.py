"""The differentiable model equals a step-by-step numpy rollout of the same dynamics."""

from __future__ import annotations

import numpy as np
import torch

from crossroads.idc.constraints import penalty, road_constraints, safety_constraints
from crossroads.idc.state import reference_point, tracking_error
from crossroads.idc.utility import utility
from crossroads.rl.model import IDCModel
from crossroads.sim.ego import ego_step
from crossroads.sim.other import other_step

from rl.rl_support import make_batch

T = 5


def numpy_rollout(path_set, ego, others, kappa, path, stop, actions, xis):
    """One sample, step by step with the numpy world functions."""
    c = path_set.candidates[path]
    speed = c.v_stop if stop else c.v_pass

    def state(e, o):
        ref = reference_point(c.points, c.heading, speed, e[0], e[1])
        return np.concatenate([e, tracking_error(e, ref.x, ref.y, ref.heading, ref.v), o.ravel()]), ref

    s, _ = state(ego, others)
    j_track = j_safe = 0.0
    for i in range(T):
        l, _ = utility(s, actions[i])
        ego = ego_step(ego, actions[i])
        others = other_step(others, kappa, xis[i])
        s, ref = state(ego, others)
        g = np.concatenate([safety_constraints(s), road_constraints(s, ref.x, ref.y, ref.heading)])
        j_track += float(l)
        j_safe += float(penalty(g))
    return j_track, j_safe


def test_rollout_matches_numpy_step_by_step(path_set) -> None:
    batch = make_batch(path_set, 6, seed=3, dtype=torch.float64)
    model = IDCModel(path_set.tensors(dtype=torch.float64))
    rng = np.random.default_rng(1)
    actions = rng.uniform([-0.4, -4.5], [0.4, 4.5], (T, 6, 2))
    xis = rng.uniform([-0.8, -0.8, -0.075, -0.025], [0.8, 0.8, 0.225, 0.025], (T, 6, 16, 4))
    out = model.rollout(batch, lambda s, i: torch.as_tensor(actions[i]), lambda s, i: torch.as_tensor(xis[i]), T)
    assert out.j_safe.sum() > 0, "the test batch should violate some constraints"
    for b in range(6):
        jt, js = numpy_rollout(path_set, batch.ego[b].numpy(), batch.others[b].numpy(), batch.kappa[b].numpy(),
                               int(batch.path[b]), bool(batch.stop[b]), actions[:, b], xis[:, b])
        np.testing.assert_allclose(out.j_track[b].item(), jt, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(out.j_safe[b].item(), js, rtol=1e-9, atol=1e-9)


def test_dpg_rollout_is_xi_zero(path_set) -> None:
    batch = make_batch(path_set, 4, seed=5, dtype=torch.float64)
    model = IDCModel(path_set.tensors(dtype=torch.float64))
    act = lambda s, i: torch.full((4, 2), 0.1, dtype=torch.float64)  # noqa: E731
    none = model.rollout(batch, act, None, T)
    zero = model.rollout(batch, act, lambda s, i: torch.zeros(4, 16, 4, dtype=torch.float64), T)
    assert torch.equal(none.j_track, zero.j_track) and torch.equal(none.j_safe, zero.j_safe)


def test_gradients_reach_actions_and_xi(path_set) -> None:
    batch = make_batch(path_set, 4, seed=7)
    model = IDCModel(path_set.tensors())
    u = torch.zeros(T, 4, 2, requires_grad=True)
    xi = torch.zeros(T, 4, 16, 4, requires_grad=True)
    out = model.rollout(batch, lambda s, i: u[i], lambda s, i: xi[i], T)
    (out.j_track + 15.0 * out.j_safe).sum().backward()
    assert u.grad.abs().sum() > 0 and xi.grad.abs().sum() > 0
