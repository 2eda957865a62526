"""The three networks of APG (SPEC §6, paper Sec. V-A): driving policy π_θ, adversary π_φ, value v_w.

All take the 108-dimensional state s (layout :mod:`crossroads.idc.state`) and feed
``network_input(s)`` (normalised, ego-relative) to an MLP of ``hidden_layers × hidden_units`` GELU
layers (paper: 5 × 256).

* Policies output the mean and the log-std of a diagonal Gaussian over a pre-squash variable z;
  ``tanh(z)`` is mapped affinely from [−1, 1] onto [low, high] of each output (the action ranges
  Δδ ∈ ±0.4 rad/s, Δa ∈ ±4.5 m/s³; the ξ ranges of ``constants.XI_RANGES``, the asymmetric
  ξ_v ∈ [−0.075, 0.225] m/s included: tanh = 0 maps to the middle of the range, 0.075 m/s).
  :meth:`SquashedGaussianPolicy.mean_action` is tanh(mean) mapped (deterministic, online use);
  :meth:`SquashedGaussianPolicy.sample` draws z = mean + std·ε (reparameterised: differentiable in
  the parameters, training). The log-std is clamped to [LOG_STD_MIN, LOG_STD_MAX] **(choice)**.
* Adversary **(choice)**: one ξ = [ξ_x, ξ_y, ξ_v, ξ_φ] for each of the 16 participant slots of the
  state (64 outputs), because f_other moves every participant with its own ξ and the worst case of a
  conflict is a disturbance of that one participant; a single shared ξ would push every participant
  the same way. Virtual (padded) participants get a ξ too; they are too far away for it to matter.
* Value v_w(s, τ): the same trunk, one output through ReLU (a non-negative path value). The path τ
  enters through x_track of s (each candidate path gives its own state).
* ``preview`` **(choice, off by default)**: the networks also read the path preview of preview states
  (``idc.state``, 120 values: the path 5-20 m ahead), 12 more inputs. :func:`widen_first_layer`
  loads a network trained without it into one with it, the new inputs' weights zero, so the warm
  start computes exactly what the source did until training gives them weight.
* ``lead`` **(choice, off by default)**: the networks also read the lead summary of
  :func:`crossroads.idc.state.lead_features` (3 inputs after the state's, computed from it: the
  nearest participant in the corridor ahead, whichever slot holds it). Warm starts widen the same way.
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

import torch
from torch import Tensor, nn

from crossroads.constants import JERK_MAX, LEAD_DIM, PREVIEW_DIM, STATE_DIM, STEER_RATE_MAX, XI_RANGES
from crossroads.idc.state import N_OTHERS, network_input

LOG_STD_MIN = -5.0  # (choice) std ≥ e⁻⁵ ≈ 0.007 in z
LOG_STD_MAX = 1.0  # (choice) std ≤ e ≈ 2.7 in z (tanh saturates beyond)
LOG_STD_INIT = -1.0  # (choice) initial log-std (bias of the log-std outputs)

ACTION_LOW = (-STEER_RATE_MAX, -JERK_MAX)  # [rad/s], [m/s³]
ACTION_HIGH = (STEER_RATE_MAX, JERK_MAX)
XI_KEYS = ("x", "y", "v", "phi")  # order of ξ as other_step takes it
XI_LOW = tuple(XI_RANGES[k][0] for k in XI_KEYS)  # [m, m, m/s, rad]
XI_HIGH = tuple(XI_RANGES[k][1] for k in XI_KEYS)
XI_DIM = len(XI_KEYS) * N_OTHERS  # 64


def mlp(in_dim: int, out_dim: int, hidden_layers: int, hidden_units: int) -> nn.Sequential:
    """``hidden_layers`` × (Linear, GELU), then a linear output layer."""
    layers: list[nn.Module] = []
    width = in_dim
    for _ in range(hidden_layers):
        layers += [nn.Linear(width, hidden_units), nn.GELU()]
        width = hidden_units
    layers.append(nn.Linear(width, out_dim))
    return nn.Sequential(*layers)


class SquashedGaussianPolicy(nn.Module):
    """s[..., 108] → a diagonal Gaussian in z, squashed by tanh onto [low, high] per output."""

    def __init__(self, low: tuple[float, ...], high: tuple[float, ...], hidden_layers: int,
                 hidden_units: int, preview: bool = False, lead: bool = False) -> None:
        super().__init__()
        self.dim = len(low)
        self.preview = preview
        self.lead = lead
        self.net = mlp(network_width(preview, lead), 2 * self.dim, hidden_layers, hidden_units)
        with torch.no_grad():
            out = self.net[-1]
            assert isinstance(out, nn.Linear)
            out.weight[self.dim:].mul_(0.01)
            out.bias[self.dim:].fill_(LOG_STD_INIT)
        self.register_buffer("low", torch.tensor(low, dtype=torch.float32))
        self.register_buffer("high", torch.tensor(high, dtype=torch.float32))

    def distribution(self, states: Tensor) -> tuple[Tensor, Tensor]:
        """(mean, log_std) of z, each ``[..., dim]``."""
        out = self.net(network_input(states, self.preview, self.lead).to(self.low.dtype))
        mean, log_std = out[..., : self.dim], out[..., self.dim:]
        return mean, torch.clamp(log_std, LOG_STD_MIN, LOG_STD_MAX)

    def squash(self, z: Tensor) -> Tensor:
        """tanh(z) mapped from [−1, 1] onto [low, high]."""
        return self.low + (torch.tanh(z) + 1.0) * (0.5 * (self.high - self.low))

    def mean_action(self, states: Tensor) -> Tensor:
        """The deterministic output: squash(mean)."""
        mean, _ = self.distribution(states)
        return self.squash(mean)

    def sample(self, states: Tensor, generator: torch.Generator | None = None) -> Tensor:
        """A reparameterised draw squash(mean + std·ε), ε ~ N(0, I): differentiable in θ."""
        mean, log_std = self.distribution(states)
        eps = torch.randn(mean.shape, dtype=mean.dtype, device=mean.device, generator=generator)
        return self.squash(mean + torch.exp(log_std) * eps)

    def forward(self, states: Tensor, deterministic: bool = False) -> Tensor:
        return self.mean_action(states) if deterministic else self.sample(states)


class DrivingPolicy(SquashedGaussianPolicy):
    """π_θ: u = [Δδ, Δa] within ±0.4 rad/s, ±4.5 m/s³."""

    def __init__(self, hidden_layers: int, hidden_units: int, preview: bool = False, lead: bool = False) -> None:
        super().__init__(ACTION_LOW, ACTION_HIGH, hidden_layers, hidden_units, preview, lead)


class Adversary(SquashedGaussianPolicy):
    """π_φ: ξ for each of the 16 participant slots, shape ``[..., 16, 4]`` (ξ_x, ξ_y, ξ_v, ξ_φ)."""

    def __init__(self, hidden_layers: int, hidden_units: int, preview: bool = False, lead: bool = False) -> None:
        super().__init__(XI_LOW * N_OTHERS, XI_HIGH * N_OTHERS, hidden_layers, hidden_units, preview, lead)

    def mean_action(self, states: Tensor) -> Tensor:
        out = super().mean_action(states)
        return out.reshape(tuple(out.shape[:-1]) + (N_OTHERS, len(XI_KEYS)))

    def sample(self, states: Tensor, generator: torch.Generator | None = None) -> Tensor:
        out = super().sample(states, generator)
        return out.reshape(tuple(out.shape[:-1]) + (N_OTHERS, len(XI_KEYS)))


class ValueNet(nn.Module):
    """v_w(s, τ) ≥ 0: the predicted J_track of following path τ (in x_track of s) from s."""

    def __init__(self, hidden_layers: int, hidden_units: int, preview: bool = False, lead: bool = False) -> None:
        super().__init__()
        self.preview = preview
        self.lead = lead
        self.net = mlp(network_width(preview, lead), 1, hidden_layers, hidden_units)
        with torch.no_grad():  # (choice) start in ReLU's active region, so no sample begins dead
            out = self.net[-1]
            assert isinstance(out, nn.Linear)
            out.bias.fill_(1.0)

    def forward(self, states: Tensor) -> Tensor:
        param = next(self.parameters())
        return torch.relu(self.net(network_input(states, self.preview, self.lead).to(param.dtype))).squeeze(-1)


class Networks(NamedTuple):
    """The networks of one run; ``adversary`` is None for DPG."""

    policy: DrivingPolicy
    value: ValueNet
    adversary: Adversary | None


def make_networks(algo: str, hidden_layers: int, hidden_units: int, device: str | torch.device = "cpu",
                  preview: bool = False, lead: bool = False) -> Networks:
    """Fresh networks (parameters drawn from torch's global RNG: seed it first); ``preview``: they
    read the path preview too, ``lead``: the lead summary (module docstring)."""
    policy = DrivingPolicy(hidden_layers, hidden_units, preview, lead).to(device)
    value = ValueNet(hidden_layers, hidden_units, preview, lead).to(device)
    adversary = Adversary(hidden_layers, hidden_units, preview, lead).to(device) if algo == "apg" else None
    return Networks(policy, value, adversary)


def input_width(preview: bool) -> int:
    """Values of the states a network takes: the 108 of SPEC §4, and the 12 of the path preview
    with ``preview``."""
    return STATE_DIM + (PREVIEW_DIM if preview else 0)


def network_width(preview: bool, lead: bool = False) -> int:
    """Inputs of a network's first layer: its states' values and, with ``lead``, the lead summary
    computed from them."""
    return input_width(preview) + (LEAD_DIM if lead else 0)


FIRST_LAYER_WEIGHT = "net.0.weight"


def _input_blocks(width: int) -> dict[str, slice] | None:
    """Where each block of a first layer ``width`` inputs wide sits (state, then the path preview,
    then the lead summary: :func:`network_width`); None for a width no layout gives."""
    for preview, lead in itertools.product((False, True), repeat=2):
        if network_width(preview, lead) == width:
            sizes = {"state": STATE_DIM, "path_preview": PREVIEW_DIM * preview, "lead_input": LEAD_DIM * lead}
            ends = dict(zip(sizes, itertools.accumulate(sizes.values()), strict=True))
            return {name: slice(ends[name] - size, ends[name]) for name, size in sizes.items() if size}
    return None


def widen_first_layer(state: dict[str, Tensor], net: nn.Module) -> dict[str, Tensor]:
    """``state`` (a state dict) fitted to ``net``: where ``net`` reads input blocks the source did not
    (the path preview, the lead summary: a warm start that adds them), the source's weights go to the
    blocks both read and the new blocks' weights are zero, so the result computes exactly what
    ``state`` did. A source reading a block ``net`` does not is refused (its inputs would be dropped
    unnoticed). Anything else passes unchanged (``load_state_dict`` then reports a real mismatch)."""
    own = net.state_dict().get(FIRST_LAYER_WEIGHT)
    weight = state.get(FIRST_LAYER_WEIGHT)
    if own is None or weight is None or weight.shape == own.shape or weight.shape[0] != own.shape[0]:
        return state
    source, target = _input_blocks(weight.shape[1]), _input_blocks(own.shape[1])
    if source is None or target is None:
        return state
    if not source.keys() <= target.keys():
        raise ValueError(f"the source networks read {weight.shape[1]} inputs ({', '.join(source)}) and these "
                         f"{own.shape[1]} ({', '.join(target)}): set path_preview and lead_input as the "
                         f"source had them to start from it")
    wider = torch.zeros_like(own)
    for name, columns in source.items():
        wider[:, target[name]] = weight[:, columns]
    return {**state, FIRST_LAYER_WEIGHT: wider}


def parameter_count(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())


assert math.isclose(XI_LOW[2], -0.075) and math.isclose(XI_HIGH[2], 0.225)
