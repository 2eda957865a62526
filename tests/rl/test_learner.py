"""The three steps of Algorithm 1 move exactly their own network, in the right direction."""

from __future__ import annotations

import pytest
import torch

from crossroads.rl.config import TrainConfig
from crossroads.rl.learner import Learner

from rl.rl_support import make_batch

TINY = dict(batch_size=8, horizon=5, hidden_layers=2, hidden_units=32, iterations=100)


def params(module):
    return [p.detach().clone() for p in module.parameters()]


def moved(before, module) -> bool:
    return any(not torch.equal(a, b) for a, b in zip(before, module.parameters()))


def learner(model, **kw) -> Learner:
    torch.manual_seed(0)
    return Learner(TrainConfig(**{**TINY, **kw}), model)


def test_policy_step_moves_theta_only(model, path_set) -> None:
    lr = learner(model)
    batch = make_batch(path_set, 8, seed=11)
    theta, phi, w = params(lr.nets.policy), params(lr.nets.adversary), params(lr.nets.value)
    lr.update(batch, 1, value=False, policy=True, adversary=False)
    assert moved(theta, lr.nets.policy)
    assert not moved(phi, lr.nets.adversary) and not moved(w, lr.nets.value)


def test_value_step_moves_w_only(model, path_set) -> None:
    lr = learner(model)
    batch = make_batch(path_set, 8, seed=11)
    theta, phi, w = params(lr.nets.policy), params(lr.nets.adversary), params(lr.nets.value)
    lr.update(batch, 1, value=True, policy=False, adversary=False)
    assert moved(w, lr.nets.value)
    assert not moved(theta, lr.nets.policy) and not moved(phi, lr.nets.adversary)


def test_adversary_step_moves_phi_only_and_increases_j_pi(model, path_set) -> None:
    lr = learner(model, sample_actions=False)  # deterministic rollouts: J_π comparable before/after
    batch = make_batch(path_set, 8, seed=11)
    _, before, _ = lr.losses(batch)
    theta, phi, w = params(lr.nets.policy), params(lr.nets.adversary), params(lr.nets.value)
    lr.update(batch, 0, value=False, policy=False, adversary=True)
    _, after, _ = lr.losses(batch)
    assert moved(phi, lr.nets.adversary)
    assert not moved(theta, lr.nets.policy) and not moved(w, lr.nets.value)
    assert after.item() > before.item()


def test_policy_step_decreases_j_pi(model, path_set) -> None:
    lr = learner(model, sample_actions=False)
    batch = make_batch(path_set, 8, seed=11)
    _, before, _ = lr.losses(batch)
    lr.update(batch, 1, value=False, policy=True, adversary=False)
    _, after, _ = lr.losses(batch)
    assert after.item() < before.item()


def test_schedule_of_the_adversary_and_dpg(model, path_set) -> None:
    lr = learner(model)
    assert [k for k in range(11) if lr.adversary_due(k)] == [0, 5, 10]
    dpg = learner(model, algo="dpg")
    assert dpg.nets.adversary is None and not dpg.adversary_due(0)
    theta = params(dpg.nets.policy)
    dpg.update(make_batch(path_set, 8, seed=2), 0)
    assert moved(theta, dpg.nets.policy)


@pytest.mark.filterwarnings("ignore:Detected call of `lr_scheduler.step")
def test_cosine_annealing_reaches_the_end_rates(model, path_set) -> None:
    lr = learner(model, iterations=4)
    for _ in range(4):
        for s in (lr.policy_sched, lr.value_sched, lr.adversary_sched):
            s.step()
    rates = lr.lrs()
    assert abs(rates["policy"] - 2e-6) < 1e-12 and abs(rates["value"] - 1e-6) < 1e-12
    assert abs(rates["adversary"] - 2e-6) < 1e-12


def saturate_braking(lr: Learner, z: float = 6.0) -> None:
    """Push the policy's pre-tanh Δa mean to about ``z`` in every state (tanh'(6) ≈ 2e-5)."""
    out = lr.nets.policy.net[-1]
    with torch.no_grad():
        out.weight[1].zero_()
        out.bias[1] = -z


def test_the_saturated_share_is_measured(model, path_set) -> None:
    lr = learner(model, sample_actions=False)
    saturate_braking(lr, z=6.0)
    batch = make_batch(path_set, 8, seed=11)
    with torch.no_grad():  # the first state's Δδ mean, as a check that only Δa is saturated
        mean, _ = lr.nets.policy.distribution(lr.model.initial_states(batch))
    assert mean[:, 0].abs().max() < 2.5 and torch.allclose(mean[:, 1], torch.tensor(-6.0))
    # Δa at z = −6 in every state of the rollout, Δδ inside the bound: half the outputs saturated
    losses = lr.update(batch, 1, value=False, adversary=False)
    assert losses.saturated_share == pytest.approx(0.5, abs=0.05)


@pytest.mark.parametrize("variant", [{"policy_loss": "log"}, {"policy_loss": "sqrt"}])
def test_the_policys_own_loss_leaves_the_adversary_step_alone(model, path_set, variant) -> None:
    batch = make_batch(path_set, 8, seed=11)
    runs = []
    for overrides in ({}, variant):
        lr = learner(model, sample_actions=False, **overrides)
        saturate_braking(lr)
        lr.update(batch, 0, value=False, policy=True, adversary=True)
        runs.append((params(lr.nets.policy), params(lr.nets.adversary)))
    (theta0, phi0), (theta1, phi1) = runs
    assert all(torch.equal(a, b) for a, b in zip(phi0, phi1))  # the adversary's step is J_π's only
    assert any(not torch.equal(a, b) for a, b in zip(theta0, theta1))


def test_log_policy_loss_decreases_j_pi(model, path_set) -> None:
    lr = learner(model, sample_actions=False, policy_loss="log")
    batch = make_batch(path_set, 8, seed=11)
    _, before, _ = lr.losses(batch)
    lr.update(batch, 1, value=False, policy=True, adversary=False)
    _, after, _ = lr.losses(batch)
    assert after.item() < before.item()
