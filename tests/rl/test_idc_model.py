"""The differentiable model equals a step-by-step numpy rollout of the same dynamics."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest
import torch

from crossroads.idc.constraints import SAFETY_MARGIN_M, penalty, road_constraints, safety_constraints
from crossroads.idc.state import OTHERS, PathTensors, path_tensors, reference_point, tracking_error
from crossroads.idc.utility import utility
from crossroads.intersections import catalogue
from crossroads.rl.buffer import StateBatch
from crossroads.rl.idc_model import IDCModel
from crossroads.sim.config import WorldConfig
from crossroads.sim.ego import ego_step
from crossroads.sim.other import other_step
from crossroads.sim.traffic import NO_TRAFFIC
from crossroads.sim.world import World

from rl.rl_support import make_batch

T = 5


def numpy_rollout(path_set, ego, others, kappa, path, stop, actions, xis):
    """One sample, step by step with the numpy world functions: ξ_x, ξ_y displace each step's
    positions from a course that only ξ_v, ξ_φ drive."""
    c = path_set.candidates[path]
    speed = c.v_stop if stop else c.v_pass

    def state(e, o):
        ref = reference_point(c.points, c.heading, speed, e[0], e[1])
        return np.concatenate([e, tracking_error(e, ref.x, ref.y, ref.heading, ref.v), o.ravel()]), ref

    s, _ = state(ego, others)
    j_track = j_safe = 0.0
    overlap = -np.inf
    course = others
    for i in range(T):
        l, _ = utility(s, actions[i])
        ego = ego_step(ego, actions[i])
        course = other_step(course, kappa, xis[i] * np.array([0.0, 0.0, 1.0, 1.0]))
        others = course.copy()
        others[:, :2] += xis[i][:, :2]
        s, ref = state(ego, others)
        g_safe = safety_constraints(s)
        g = np.concatenate([g_safe, road_constraints(s, ref.x, ref.y, ref.heading)])
        j_track += float(l)
        j_safe += float(penalty(g))
        overlap = max(overlap, float(g_safe.max()) - SAFETY_MARGIN_M)
    return j_track, j_safe, overlap


def test_rollout_matches_numpy_step_by_step(path_set) -> None:
    batch = make_batch(path_set, 6, seed=3, dtype=torch.float64)
    model = IDCModel(path_set.tensors(dtype=torch.float64))
    rng = np.random.default_rng(1)
    actions = rng.uniform([-0.4, -4.5], [0.4, 4.5], (T, 6, 2))
    xis = rng.uniform([-0.8, -0.8, -0.075, -0.025], [0.8, 0.8, 0.225, 0.025], (T, 6, 16, 4))
    out = model.rollout(batch, lambda s, i: torch.as_tensor(actions[i]), lambda s, i: torch.as_tensor(xis[i]), T)
    assert out.j_safe.sum() > 0, "the test batch should violate some constraints"
    for b in range(6):
        jt, js, overlap = numpy_rollout(path_set, batch.ego[b].numpy(), batch.others[b].numpy(), batch.kappa[b].numpy(),
                               int(batch.path[b]), bool(batch.stop[b]), actions[:, b], xis[:, b])
        np.testing.assert_allclose(out.j_track[b].item(), jt, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(out.j_safe[b].item(), js, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(out.overlap_m[b].item(), overlap, rtol=1e-9, atol=1e-9)
    assert (out.overlap_m > 0).any() and (out.overlap_m < 0).any(), "the batch should hold both"


def test_xi_positions_do_not_accumulate(path_set) -> None:
    """A constant ξ_x = 0.8 m keeps a participant 0.8 m off its ξ ≡ 0 course at every step after
    the first, never further (as printed, f_other would carry it 0.8 m further every step)."""
    batch = make_batch(path_set, 1, seed=2, dtype=torch.float64)
    push = torch.zeros(1, 16, 4, dtype=torch.float64)
    push[..., 0] = 0.8
    model = IDCModel(path_set.tensors(dtype=torch.float64))
    seen: dict[str, list[float]] = {"pushed": [], "zero": []}
    for xs, xi in zip(seen.values(), (push, torch.zeros_like(push))):

        def act(s, i, xs=xs):
            xs.append(float(s[0, OTHERS.start]))  # first participant's p_x as the step sees it
            return torch.zeros(1, 2, dtype=torch.float64)

        model.rollout(batch, act, lambda s, i, xi=xi: xi, T)
    off = np.subtract(seen["pushed"], seen["zero"])
    np.testing.assert_allclose(off, [0.0] + [0.8] * (T - 1), atol=1e-9)


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


def test_nominal_floor_is_never_milder_than_either_prediction(path_set) -> None:
    """Each constraint is the worse of the adversary's and the ξ ≡ 0 scene: J_safe is at least that
    of either scene alone and at most their sum; J_track and the ego's states do not change."""
    batch = make_batch(path_set, 6, seed=3, dtype=torch.float64)
    rng = np.random.default_rng(4)
    actions = torch.as_tensor(rng.uniform([-0.4, -4.5], [0.4, 4.5], (T, 6, 2)))
    xis = torch.as_tensor(rng.uniform([-0.8, -0.8, -0.075, -0.025], [0.8, 0.8, 0.225, 0.025], (T, 6, 16, 4)))
    plain = IDCModel(path_set.tensors(dtype=torch.float64))
    floored = IDCModel(path_set.tensors(dtype=torch.float64), nominal_floor=True)
    act = lambda s, i: actions[i]  # noqa: E731
    adv = lambda s, i: xis[i]  # noqa: E731
    adversarial, nominal = plain.rollout(batch, act, adv, T), plain.rollout(batch, act, None, T)
    both = floored.rollout(batch, act, adv, T)
    assert torch.equal(both.j_track, adversarial.j_track)
    assert torch.all(both.j_safe >= torch.maximum(adversarial.j_safe, nominal.j_safe) - 1e-12)
    assert torch.all(both.j_safe <= adversarial.j_safe + nominal.j_safe + 1e-12)
    assert torch.any(both.j_safe > adversarial.j_safe), "the floor should bind somewhere in this batch"
    # DPG (no adversary) and ξ ≡ 0 are untouched by the floor
    assert torch.equal(floored.rollout(batch, act, None, T).j_safe, nominal.j_safe)
    zero = floored.rollout(batch, act, lambda s, i: torch.zeros_like(xis[i]), T)
    torch.testing.assert_close(zero.j_safe, nominal.j_safe, rtol=0, atol=1e-12)


class _StraightScene(NamedTuple):
    """One ego on c_three_lane's straight path (path 1) and one car ahead on it; float64."""

    paths: PathTensors
    batch: StateBatch
    others: torch.Tensor  # (1, 16, 6): the car in slot 0, the rest far away
    x0: float
    y0: float
    heading: float


def _car_ahead_on_straight(ego_speed: float, car_ahead_m: float, car_speed: float) -> _StraightScene:
    """The ego at the start of the straight path at ``ego_speed``, a 4.8 × 1.8 m car ``car_ahead_m``
    (centres) ahead on the path at ``car_speed``, heading the path's way."""
    with World(WorldConfig(net_file=catalogue.build("c_three_lane"), task="straight", demand=NO_TRAFFIC,
                           warmup_s=1.0)) as world:
        path = world.candidates[1]
    x0, y0 = (float(v) for v in path.points[0])
    heading = float(path.heading[0])
    c, s = np.cos(heading), np.sin(heading)
    ego = torch.tensor([[x0, y0, ego_speed, 0.0, heading, 0.0, 0.0, 0.0]], dtype=torch.float64)
    others = torch.zeros(1, 16, 6, dtype=torch.float64)
    others[..., 0] = 1e4  # padding: far away
    others[0, 0] = torch.tensor([x0 + car_ahead_m * c, y0 + car_ahead_m * s, car_speed, heading, 4.8, 1.8])
    batch = StateBatch(ego, others, torch.zeros(1, 16, dtype=torch.float64), torch.tensor([0]), torch.tensor([False]))
    return _StraightScene(path_tensors([path], dtype=torch.float64), batch, others, x0, y0, heading)


def _coast(s_: torch.Tensor, i: int) -> torch.Tensor:
    """Keep a = 0."""
    return torch.zeros(1, 2, dtype=torch.float64)


def test_braking_floor_makes_a_slowing_car_ahead_bind() -> None:
    """The ego coasting at 8 m/s, 19 m (centres) behind a car doing 6 m/s on its straight path: kept at
    its speed the car stays ~14 m ahead over T = 25 steps, no constraint binds; braking at 4.5 m/s²
    it stops 4 m on and the ego runs into it: the braking floor's J_safe > 0. Nobody in reach: equal."""
    paths, batch, others, *_ = _car_ahead_on_straight(8.0, 19.0, 6.0)
    ego, coast = batch.ego, _coast
    plain = IDCModel(paths).rollout(batch, coast, None, 25)
    floored = IDCModel(paths, braking_floor=True).rollout(batch, coast, None, 25)
    assert plain.j_safe.item() == 0.0 and plain.overlap_m.item() < -5.0
    assert floored.j_safe.item() > 0.0 and floored.overlap_m.item() > 0.0
    assert torch.equal(floored.j_track, plain.j_track)
    far = StateBatch(ego, others[:, 1:2].expand(1, 16, 6).clone(), batch.kappa, batch.path, batch.stop)
    assert torch.equal(IDCModel(paths, braking_floor=True).rollout(far, coast, None, 25).j_safe,
                       IDCModel(paths).rollout(far, coast, None, 25).j_safe)


def test_stopping_tail_sees_a_standing_car_beyond_the_horizon() -> None:
    """The ego coasting at 8.33 m/s, 40 m (centres) behind a car standing on its straight path: over
    T = 25 steps it gets within ~19 m, no constraint binds; but from there full braking (~15 m) ends
    inside the safety margin, so the stopping tail's J_safe > 0. A plan that brakes from the start keeps a
    way to stop and the tail adds nothing; J_track and the overlap never change with the tail."""
    paths, batch, others, x0, y0, heading = _car_ahead_on_straight(8.33, 40.0, 0.0)
    ego, coast = batch.ego, _coast
    c, s = np.cos(heading), np.sin(heading)
    brake = lambda s_, i: torch.tensor([[0.0, -4.5]], dtype=torch.float64)  # noqa: E731
    plain = IDCModel(paths).rollout(batch, coast, None, 25)
    tailed = IDCModel(paths, stopping_tail=40).rollout(batch, coast, None, 25)
    assert plain.j_safe.item() == 0.0
    assert tailed.j_safe.item() > 0.5
    assert torch.equal(tailed.j_track, plain.j_track) and torch.equal(tailed.overlap_m, plain.overlap_m)
    assert IDCModel(paths, stopping_tail=40).rollout(batch, brake, None, 25).j_safe.item() == 0.0
    # its gradient always asks for less acceleration, also where braking comes far too late (24 m:
    # the ego's circles would pass through the car's, where a circle penalty rewards driving on)
    for gap in (24.0, 30.0, 36.0, 40.0):
        moved = others.clone()
        moved[0, 0, :2] = torch.tensor([x0 + gap * c, y0 + gap * s])
        ahead = StateBatch(ego, moved, batch.kappa, batch.path, batch.stop)
        u = torch.zeros(1, 2, dtype=torch.float64, requires_grad=True)
        j = IDCModel(paths, stopping_tail=40).rollout(ahead, lambda s_, i, u=u: u, None, 25).j_safe.sum()
        j.backward()
        assert j.item() > 0.0 and u.grad is not None and u.grad[0, 1].item() > 0.0, gap
    # a car crossing the ego's way (heading 90° off) is left to the horizon's constraints: driving
    # faster could put it behind the ego by the horizon's end, so the tail must not ask for that
    crossing = others.clone()
    crossing[0, 0, 3] = heading + np.pi / 2
    across = StateBatch(ego, crossing, batch.kappa, batch.path, batch.stop)
    assert IDCModel(paths, stopping_tail=40).rollout(across, coast, None, 25).j_safe.item() == 0.0
    with pytest.raises(ValueError, match="stopping_tail"):
        IDCModel(paths, stopping_tail=-1)
