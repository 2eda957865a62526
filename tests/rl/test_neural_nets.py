"""π_θ, π_φ, v_w: outputs within their ranges, whatever the state."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from crossroads.constants import JERK_MAX, STATE_DIM, STEER_RATE_MAX, XI_RANGES
from crossroads.rl.neural_nets import (
    MLP,
    XI_KEYS,
    Adversary,
    DrivingPolicy,
    ValueNet,
    make_networks,
    mlp,
    network_width,
    run_steps,
)

torch.manual_seed(0)
POLICY = DrivingPolicy(2, 32)
ADVERSARY = Adversary(2, 32)
VALUE = ValueNet(2, 32)
# push the pre-squash outputs to saturation too: big output weights
with torch.no_grad():
    BIG = Adversary(2, 32)
    BIG.net[-1].weight.mul_(1e3)

states = arrays(np.float64, (4, STATE_DIM), elements=st.floats(-1e3, 1e3, allow_nan=False, width=32))


@settings(max_examples=40, deadline=None)
@given(states)
def test_actions_within_their_ranges(s: np.ndarray) -> None:
    x = torch.as_tensor(s, dtype=torch.float32)
    for u in (POLICY.mean_action(x), POLICY.sample(x)):
        assert u.shape == (4, 2)
        assert torch.all(u[:, 0].abs() <= STEER_RATE_MAX) and torch.all(u[:, 1].abs() <= JERK_MAX)


@settings(max_examples=40, deadline=None)
@given(states)
def test_xi_within_its_ranges(s: np.ndarray) -> None:
    x = torch.as_tensor(s, dtype=torch.float32)
    for net in (ADVERSARY, BIG):
        for xi in (net.mean_action(x), net.sample(x)):
            assert xi.shape == (4, 16, 4)
            for k, key in enumerate(XI_KEYS):
                lo, hi = XI_RANGES[key]
                assert torch.all(xi[..., k] >= lo - 1e-7) and torch.all(xi[..., k] <= hi + 1e-7), key


def test_xi_v_range_is_asymmetric_and_fully_reachable() -> None:
    x = torch.zeros(1, STATE_DIM)
    assert torch.allclose(ADVERSARY.squash(torch.full((1, 64), -50.0))[0, 2], torch.tensor(-0.075))
    assert torch.allclose(ADVERSARY.squash(torch.full((1, 64), 50.0))[0, 2], torch.tensor(0.225))
    assert torch.allclose(ADVERSARY.squash(torch.zeros(1, 64))[0, 2], torch.tensor(0.075))
    assert ADVERSARY.mean_action(x).shape == (1, 16, 4)


@settings(max_examples=20, deadline=None)
@given(states)
def test_value_is_non_negative(s: np.ndarray) -> None:
    assert torch.all(VALUE(torch.as_tensor(s, dtype=torch.float32)) >= 0.0)


def test_mean_action_is_deterministic_and_sampling_reparameterised() -> None:
    x = torch.randn(3, STATE_DIM)
    assert torch.equal(POLICY.mean_action(x), POLICY.mean_action(x))
    u = POLICY.sample(x)
    u.sum().backward()
    assert all(p.grad is not None for p in POLICY.parameters())
    POLICY.zero_grad()


def test_paper_sizes() -> None:
    nets = make_networks("apg", 5, 256)
    linears = [m for m in nets.policy.net if isinstance(m, torch.nn.Linear)]
    assert len(linears) == 6 and all(m.out_features == 256 for m in linears[:-1])
    assert isinstance(nets.policy.net[1], torch.nn.GELU)
    assert linears[-1].out_features == 4 and nets.adversary.net[-1].out_features == 128
    assert make_networks("dpg", 5, 256).adversary is None


def test_widening_places_each_input_block_and_refuses_to_drop_one() -> None:
    import pytest

    from crossroads.constants import LEAD_DIM, PREVIEW_DIM
    from crossroads.rl.neural_nets import network_width, widen_first_layer

    assert network_width(False) == STATE_DIM and network_width(True, True) == STATE_DIM + PREVIEW_DIM + LEAD_DIM
    rng = np.random.default_rng(4)
    states = torch.tensor(rng.normal(0.0, 3.0, (8, STATE_DIM + PREVIEW_DIM)))
    # every source whose blocks the target also reads widens exactly, the lead summary without the
    # preview included (its weights move past the preview's inputs)
    for source_preview, source_lead in ((False, False), (True, False), (False, True)):
        torch.manual_seed(1)
        source = make_networks("apg", 2, 32, preview=source_preview, lead=source_lead)
        target = make_networks("apg", 2, 32, preview=True, lead=True)
        for src, dst in zip(source, target, strict=True):
            dst.load_state_dict(widen_first_layer(src.state_dict(), dst))
        seen = states if source_preview else states[:, :STATE_DIM]
        assert torch.allclose(target.policy.mean_action(states), source.policy.mean_action(seen))
        assert torch.allclose(target.value(states), source.value(seen))
    lead_only = make_networks("dpg", 2, 32, lead=True)
    with pytest.raises(ValueError, match=r"\(state, lead_input\) and these 120 \(state, path_preview\)"):
        widen_first_layer(lead_only.policy.state_dict(), make_networks("dpg", 2, 32, preview=True).policy)
    with pytest.raises(ValueError, match="set path_preview and lead_input as the source had them"):
        widen_first_layer(target.policy.state_dict(), make_networks("dpg", 2, 32, preview=True).policy)


def test_participant_pooling_reads_every_slot_of_a_kind_alike() -> None:
    """Pooled networks: the same outputs whichever slots of their kind the participants take, a
    different output when one participant moves, and the MLP as wide as trunk_width says."""
    import pytest

    from crossroads.constants import PREVIEW_DIM
    from crossroads.rl.neural_nets import trunk_width, widen_first_layer

    torch.manual_seed(2)
    nets = make_networks("apg", 2, 32, preview=True, lead=True, encoder=16)
    assert nets.policy.net[0].in_features == trunk_width(True, True, 16) == 12 + PREVIEW_DIM + 3 + 16
    assert nets.adversary is not None and nets.adversary.encoder is None  # its ξ are per slot
    rng = np.random.default_rng(5)
    s = torch.tensor(rng.normal(0.0, 10.0, (6, STATE_DIM + PREVIEW_DIM)), dtype=torch.float32)
    others = s[:, 12:STATE_DIM].reshape(6, 16, 6)
    shuffled = others.clone()
    shuffled[:, :8] = others[:, torch.tensor([5, 2, 7, 0, 1, 3, 6, 4])]  # the vehicles
    shuffled[:, 12:] = others[:, torch.tensor([15, 14, 12, 13])]  # the pedestrians
    t = s.clone()
    t[:, 12:STATE_DIM] = shuffled.reshape(6, 96)
    assert torch.allclose(nets.policy.mean_action(t), nets.policy.mean_action(s), atol=1e-6)
    assert torch.allclose(nets.value(t), nets.value(s), atol=1e-5)
    moved = s.clone()
    moved[:, 12] += 5.0  # the first vehicle 5 m further
    assert not torch.allclose(nets.policy.mean_action(moved), nets.policy.mean_action(s))
    # a cyclist is not a vehicle: swapping a vehicle slot with a cyclist slot changes the input
    swapped = others.clone()
    swapped[:, [0, 8]] = others[:, [8, 0]]
    u = s.clone()
    u[:, 12:STATE_DIM] = swapped.reshape(6, 96)
    assert not torch.allclose(nets.policy.mean_action(u), nets.policy.mean_action(s))
    flat = make_networks("apg", 2, 32, preview=True, lead=True)
    with pytest.raises(ValueError, match="distill"):
        widen_first_layer(flat.policy.state_dict(), nets.policy)
    with pytest.raises(ValueError, match="must be ≥ 0 units"):
        make_networks("dpg", 2, 32, encoder=-1)


def test_the_mlp_gives_nn_sequentials_numbers_and_keys_and_gradients() -> None:
    torch.manual_seed(1)
    net = mlp(12, 3, 3, 64)
    plain = torch.nn.Sequential(*net)
    assert list(net.state_dict()) == list(plain.state_dict())  # saved networks load unchanged
    x = torch.randn(5, 12, requires_grad=True)
    assert torch.equal(net(x), plain(x))
    (g_mlp,) = torch.autograd.grad(net(x).sum(), x)
    (g_seq,) = torch.autograd.grad(plain(x).sum(), x)
    assert torch.equal(g_mlp, g_seq)
    assert isinstance(net[:2], MLP) and torch.equal(net[:2](x), plain[:2](x))


@pytest.mark.parametrize("layer", [torch.nn.ReLU(), torch.nn.GELU(approximate="tanh"), torch.nn.Dropout()])
def test_the_mlp_refuses_layers_its_loop_does_not_run(layer: torch.nn.Module) -> None:
    with pytest.raises(TypeError, match="Linear and exact GELU"):
        MLP(torch.nn.Linear(2, 2), layer)


@pytest.mark.parametrize(("preview", "lead", "encoder", "dtype"), [
    (False, False, 0, torch.float32), (True, False, 0, torch.float32), (True, True, 16, torch.float32),
    (False, True, 0, torch.float64),
])
def test_the_fetched_functions_give_the_modules_numbers_bit_for_bit(preview: bool, lead: bool, encoder: int,
                                                                     dtype: torch.dtype) -> None:
    """value_function and mean_action_function (the online decision's fast path: parameters fetched
    once, no module call per layer) compute what value_of_input and mean_action_of_input do, bit for
    bit, on one row, a few and many; and see parameters changed in place."""
    torch.manual_seed(2)
    nets = make_networks("dpg", 5, 64, preview=preview, lead=lead, encoder=encoder)
    policy, value = nets.policy.to(dtype), nets.value.to(dtype)
    mean_action, value_of = policy.mean_action_function(), value.value_function()
    x = torch.randn(40, network_width(preview, lead), dtype=dtype) * 3.0
    with torch.inference_mode():
        for rows in (x[:1], x[:3], x[5:6], x):
            assert torch.equal(mean_action(rows), policy.mean_action_of_input(rows))
            assert torch.equal(value_of(rows), value.value_of_input(rows))
    with torch.no_grad():  # an optimiser's step: in place
        policy.net[0].weight.mul_(1.5)
        value.net[-1].bias.add_(0.25)
    with torch.inference_mode():
        assert torch.equal(mean_action(x), policy.mean_action_of_input(x))
        assert torch.equal(value_of(x), value.value_of_input(x))


def test_the_mlps_steps_are_its_layers() -> None:
    net = mlp(12, 3, 2, 16)
    steps = net.steps()
    assert [step is None for step in steps] == [False, True, False, True, False]
    assert steps[0][0] is net[0].weight and steps[-1][1] is net[-1].bias
    x = torch.randn(4, 12)
    assert torch.equal(run_steps(x, steps), net(x))
