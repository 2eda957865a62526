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
* ``encoder`` **(choice, 0 = off by default)**: the driving policy and the value network read the 16
  participants through :class:`ParticipantPooling` (one small network shared by every slot, its
  outputs max-pooled over the slots) instead of 96 slot-specific inputs, so a participant means the
  same to them whichever slot holds it and however many others are around. The adversary keeps the
  flat input: its 64 outputs are per slot. Such networks cannot be widened from flat ones; they start
  from them by distillation (:mod:`crossroads.rl.distill`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from typing import NamedTuple

from typing import TYPE_CHECKING

import torch
from torch import Tensor, nn
from torch.nn import functional as F

from crossroads.constants import (
    EGO_STATE_DIM,
    JERK_MAX,
    LEAD_DIM,
    OTHER_STATE_DIM,
    PREVIEW_DIM,
    STATE_DIM,
    STEER_RATE_MAX,
    TRACK_STATE_DIM,
    XI_RANGES,
)
from crossroads.idc.state import KIND_OF_SLOT, KINDS, N_OTHERS, network_input

LOG_STD_MIN = -5.0  # (choice) std ≥ e⁻⁵ ≈ 0.007 in z
LOG_STD_MAX = 1.0  # (choice) std ≤ e ≈ 2.7 in z (tanh saturates beyond)
LOG_STD_INIT = -1.0  # (choice) initial log-std (bias of the log-std outputs)

ACTION_LOW = (-STEER_RATE_MAX, -JERK_MAX)  # [rad/s], [m/s³]
ACTION_HIGH = (STEER_RATE_MAX, JERK_MAX)
XI_KEYS = ("x", "y", "v", "phi")  # order of ξ as other_step takes it
XI_LOW = tuple(XI_RANGES[k][0] for k in XI_KEYS)  # [m, m, m/s, rad]
XI_HIGH = tuple(XI_RANGES[k][1] for k in XI_KEYS)
XI_DIM = len(XI_KEYS) * N_OTHERS  # 64

Step = tuple[Tensor, Tensor] | None  # a Linear layer's (weight, bias), or None for an exact GELU


class MLP(nn.Sequential):
    """Linear and GELU layers, run as one loop of ``F.linear`` and ``F.gelu`` on each layer's own
    parameters: the numbers of ``nn.Sequential``'s forward, bit for bit, without a module call
    per layer (about a third of the forward pass of a batch of three states through 5 × 256 on
    one CPU thread: benchmarks/decision_latency.py). Its state dict is ``nn.Sequential``'s
    (``0.weight``, ``0.bias``, …), so saved networks load unchanged. Layers other than Linear and
    GELU are not supported."""

    def __init__(self, *layers: nn.Module) -> None:
        super().__init__(*layers)  # (nn.Sequential's slicing passes one OrderedDict of them)
        for layer in self:
            if not isinstance(layer, (nn.Linear, nn.GELU)) or (isinstance(layer, nn.GELU)
                                                               and layer.approximate != "none"):
                raise TypeError(f"MLP holds Linear and exact GELU layers only, not {layer!r}")

    def forward(self, x: Tensor) -> Tensor:
        for layer in self:
            x = F.linear(x, layer.weight, layer.bias) if isinstance(layer, nn.Linear) else F.gelu(x)
        return x

    def steps(self) -> tuple[Step, ...]:
        """Its layers for :func:`run_steps`: each Linear's (weight, bias), None for each GELU. The
        parameters themselves, not copies: what changes them in place (an optimiser,
        ``load_state_dict``) is seen; a layer or parameter replaced is not, so ask again then."""
        return tuple((layer.weight, layer.bias) if isinstance(layer, nn.Linear) else None for layer in self)


def run_steps(x: Tensor, steps: tuple[Step, ...]) -> Tensor:
    """:meth:`MLP.forward` on its :meth:`MLP.steps`: the same ``F.linear`` and ``F.gelu`` calls,
    so the same numbers bit for bit, without reading each layer's parameters through
    ``nn.Module.__getattr__`` (about 30 look-ups a decision; the online decision's fast path)."""
    for step in steps:
        x = F.gelu(x) if step is None else F.linear(x, step[0], step[1])
    return x


def mlp(in_dim: int, out_dim: int, hidden_layers: int, hidden_units: int) -> MLP:
    """``hidden_layers`` × (Linear, GELU), then a linear output layer."""
    layers: list[nn.Module] = []
    width = in_dim
    for _ in range(hidden_layers):
        layers += [nn.Linear(width, hidden_units), nn.GELU()]
        width = hidden_units
    layers.append(nn.Linear(width, out_dim))
    return MLP(*layers)


HEAD_DIM = EGO_STATE_DIM + TRACK_STATE_DIM  # the ego's and x_track's inputs, before the participants'
OTHERS_DIM = N_OTHERS * OTHER_STATE_DIM  # 96
EGO_SPEED_INPUT = 2  # network_input's v_x / 10 m/s (idc.state)
PARTICIPANT_FEATURES = OTHER_STATE_DIM + len(KINDS) + 1  # its 6 inputs, its kind one-hot, the ego's speed


class ParticipantPooling(nn.Module):
    """``network_input`` [..., W] → [..., W − 96 + units]: the ego's and x_track's inputs, the
    inputs after the participants' (path preview, lead summary), then the participants pooled.

    Each slot's 6 ego-frame inputs, its kind as a one-hot and the ego's speed go through one shared
    2-layer GELU network of ``units``; the elementwise max over the 16 slots is the pooled vector.
    Why (docs/tried/training.md, "Pooled participants"): the flat 5 × 256 networks read each slot
    with its own weights, and the shipped APG's policy, 2 s before a collision with a vehicle ahead, planned
    to keep clear of that vehicle alone in the first slot in 29 of 32 states but only in 4 of 32
    alone in the slot it had as seen. The max over a shared encoding cannot depend on the slot, and
    one participant's encoding not on the others. The ego's speed is in every slot's input so that
    how soon a participant is reached is encoded with it. Pads take part like any participant: they
    all encode alike (100 m behind, standing), so they add one fixed vector to the max."""

    def __init__(self, units: int) -> None:
        super().__init__()
        self.units = units
        self.encode = MLP(nn.Linear(PARTICIPANT_FEATURES, units), nn.GELU(),
                          nn.Linear(units, units), nn.GELU())
        kinds = torch.zeros(N_OTHERS, len(KINDS))
        for slot, kind in enumerate(KIND_OF_SLOT):
            kinds[slot, KINDS.index(kind)] = 1.0
        self.register_buffer("kinds", kinds)

    def forward(self, x: Tensor) -> Tensor:
        return _pool(x, self.encode.steps(), self.kinds)

    def function(self) -> Callable[[Tensor], Tensor]:
        """:meth:`forward` as a function of the parameters and slot kinds fetched now (as
        :meth:`MLP.steps`): the same operations, so the same numbers bit for bit, without the
        module calls; for the online decision's fast path."""
        steps, kinds = self.encode.steps(), self.kinds

        def pool(x: Tensor) -> Tensor:
            return _pool(x, steps, kinds)

        return pool


def _pool(x: Tensor, steps: tuple[Step, ...], kinds: Tensor) -> Tensor:
    """:meth:`ParticipantPooling.forward` on the encoder's :meth:`MLP.steps` and its slot kinds."""
    lead = x.shape[:-1]
    others = x[..., HEAD_DIM:HEAD_DIM + OTHERS_DIM].reshape(lead + (N_OTHERS, OTHER_STATE_DIM))
    speed = x[..., EGO_SPEED_INPUT, None, None].expand(lead + (N_OTHERS, 1))
    features = torch.cat([others, kinds.to(x.dtype).expand(lead + kinds.shape), speed], dim=-1)
    pooled = run_steps(features, steps).amax(dim=-2)
    return torch.cat([x[..., :HEAD_DIM], x[..., HEAD_DIM + OTHERS_DIM:], pooled], dim=-1)


def trunk_width(preview: bool, lead: bool, encoder: int) -> int:
    """Inputs of the MLP: :func:`network_width`, or with a participant encoder of ``encoder`` units
    the 96 participant inputs replaced by the pooled ``encoder`` values."""
    width = network_width(preview, lead)
    return width if encoder == 0 else width - OTHERS_DIM + encoder


def participant_pooling(encoder: int) -> ParticipantPooling | None:
    if encoder < 0:
        raise ValueError(f"participant_encoder: must be ≥ 0 units, got {encoder}")
    return ParticipantPooling(encoder) if encoder else None


class SquashedGaussianPolicy(nn.Module):
    """s[..., 108] → a diagonal Gaussian in z, squashed by tanh onto [low, high] per output."""

    def __init__(self, low: tuple[float, ...], high: tuple[float, ...], hidden_layers: int,
                 hidden_units: int, preview: bool = False, lead: bool = False, encoder: int = 0) -> None:
        super().__init__()
        self.dim = len(low)
        self.preview = preview
        self.lead = lead
        self.encoder = participant_pooling(encoder)
        self.net = mlp(trunk_width(preview, lead, encoder), 2 * self.dim, hidden_layers, hidden_units)
        with torch.no_grad():
            out = self.net[-1]
            assert isinstance(out, nn.Linear)
            out.weight[self.dim:].mul_(0.01)
            out.bias[self.dim:].fill_(LOG_STD_INIT)
        self.register_buffer("low", torch.tensor(low, dtype=torch.float32))
        self.register_buffer("high", torch.tensor(high, dtype=torch.float32))

    def distribution(self, states: Tensor) -> tuple[Tensor, Tensor]:
        """(mean, log_std) of z, each ``[..., dim]``."""
        return self.distribution_of_input(network_input(states, self.preview, self.lead).to(self.low.dtype))

    def distribution_of_input(self, x: Tensor) -> tuple[Tensor, Tensor]:
        """:meth:`distribution` of states already through :func:`network_input` (in this network's
        dtype): an online decision normalises its candidates' states once for both networks."""
        out = self.net(x if self.encoder is None else self.encoder(x))
        mean, log_std = out[..., : self.dim], out[..., self.dim:]
        return mean, torch.clamp(log_std, LOG_STD_MIN, LOG_STD_MAX)

    def squash(self, z: Tensor) -> Tensor:
        """tanh(z) mapped from [−1, 1] onto [low, high]."""
        return self.low + (torch.tanh(z) + 1.0) * (0.5 * (self.high - self.low))

    def mean_action(self, states: Tensor) -> Tensor:
        """The deterministic output: squash(mean)."""
        mean, _ = self.distribution(states)
        return self.squash(mean)

    def mean_action_of_input(self, x: Tensor) -> Tensor:
        """:meth:`mean_action` of states already through :func:`network_input` (this class's flat
        output; the adversary's ``mean_action`` reshapes its own)."""
        return self.squash(self.distribution_of_input(x)[0])

    def mean_action_function(self) -> Callable[[Tensor], Tensor]:
        """:meth:`mean_action_of_input` as a function of this network's parameters fetched now
        (:meth:`MLP.steps`): the same torch operations, so the same numbers bit for bit, without a
        module call or attribute look-up per layer, nor the log-std a mean action does not need.
        For the online decision (one row a step, under ``torch.inference_mode``); fetch it again
        after replacing the parameters or buffers (``.to`` another dtype or device)."""
        steps, dim, low = self.net.steps(), self.dim, self.low
        encode = None if self.encoder is None else self.encoder.function()
        half_range = 0.5 * (self.high - self.low)  # squash's factor, the same float32 each call

        def mean_action(x: Tensor) -> Tensor:
            out = run_steps(x if encode is None else encode(x), steps)
            return low + (torch.tanh(out[..., :dim]) + 1.0) * half_range

        return mean_action

    def sample(self, states: Tensor, generator: torch.Generator | None = None) -> Tensor:
        """A reparameterised draw squash(mean + std·ε), ε ~ N(0, I): differentiable in θ."""
        mean, log_std = self.distribution(states)
        eps = torch.randn(mean.shape, dtype=mean.dtype, device=mean.device, generator=generator)
        return self.squash(mean + torch.exp(log_std) * eps)

    def forward(self, states: Tensor, deterministic: bool = False) -> Tensor:
        return self.mean_action(states) if deterministic else self.sample(states)


class DrivingPolicy(SquashedGaussianPolicy):
    """π_θ: u = [Δδ, Δa] within ±0.4 rad/s, ±4.5 m/s³."""

    def __init__(self, hidden_layers: int, hidden_units: int, preview: bool = False, lead: bool = False,
                 encoder: int = 0) -> None:
        super().__init__(ACTION_LOW, ACTION_HIGH, hidden_layers, hidden_units, preview, lead, encoder)


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

    def __init__(self, hidden_layers: int, hidden_units: int, preview: bool = False, lead: bool = False,
                 encoder: int = 0) -> None:
        super().__init__()
        self.preview = preview
        self.lead = lead
        self.encoder = participant_pooling(encoder)
        self.net = mlp(trunk_width(preview, lead, encoder), 1, hidden_layers, hidden_units)
        with torch.no_grad():  # (choice) start in ReLU's active region, so no sample begins dead
            out = self.net[-1]
            assert isinstance(out, nn.Linear)
            out.bias.fill_(1.0)

    def forward(self, states: Tensor) -> Tensor:
        param = next(self.parameters())
        return self.value_of_input(network_input(states, self.preview, self.lead).to(param.dtype))

    def value_of_input(self, x: Tensor) -> Tensor:
        """:meth:`forward` of states already through :func:`network_input` (in this network's dtype)."""
        return torch.relu(self.net(x if self.encoder is None else self.encoder(x))).squeeze(-1)

    def value_function(self) -> Callable[[Tensor], Tensor]:
        """:meth:`value_of_input` as a function of this network's parameters fetched now: the same
        numbers bit for bit, for the online decision (as :meth:`SquashedGaussianPolicy.mean_action_function`)."""
        steps = self.net.steps()
        encode = None if self.encoder is None else self.encoder.function()

        def value(x: Tensor) -> Tensor:
            return torch.relu(run_steps(x if encode is None else encode(x), steps)).squeeze(-1)

        return value


class Networks(NamedTuple):
    """The networks of one run; ``adversary`` is None for DPG."""

    policy: DrivingPolicy
    value: ValueNet
    adversary: Adversary | None


def make_networks(algo: str, hidden_layers: int, hidden_units: int, device: str | torch.device = "cpu",
                  preview: bool = False, lead: bool = False, encoder: int = 0) -> Networks:
    """Fresh networks (parameters drawn from torch's global RNG: seed it first); ``preview``: they
    read the path preview too, ``lead``: the lead summary, ``encoder`` > 0: the policy and the value
    network pool the participants (module docstring)."""
    policy = DrivingPolicy(hidden_layers, hidden_units, preview, lead, encoder).to(device)
    value = ValueNet(hidden_layers, hidden_units, preview, lead, encoder).to(device)
    adversary = Adversary(hidden_layers, hidden_units, preview, lead).to(device) if algo == "apg" else None
    return Networks(policy, value, adversary)


def networks_for(config: TrainConfig, device: str | torch.device = "cpu") -> Networks:
    """Fresh networks of the layout ``config`` names (:func:`make_networks`)."""
    return make_networks(config.algo, config.hidden_layers, config.hidden_units, device, config.path_preview,
                         config.lead_input, config.participant_encoder)


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
    own_state = net.state_dict()
    own = own_state.get(FIRST_LAYER_WEIGHT)
    weight = state.get(FIRST_LAYER_WEIGHT)
    pooled_here = any(key.startswith("encoder.") for key in own_state)
    pooled_there = any(key.startswith("encoder.") for key in state)
    if pooled_here != pooled_there:
        raise ValueError("the source networks read the participants " + ("flat" if pooled_here else "pooled")
                         + " and these " + ("pooled" if pooled_here else "flat") + " (participant_encoder): "
                         "distill the source into the new layout first (crossroads train distill)")
    if own is None or weight is None or weight.shape == own.shape or weight.shape[0] != own.shape[0]:
        return state
    if pooled_here:
        raise ValueError(f"networks with a participant encoder read {own.shape[1]} inputs and the source "
                         f"{weight.shape[1]}: set path_preview, lead_input and participant_encoder as the source "
                         f"had them (widening pooled networks is not supported)")
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


if TYPE_CHECKING:
    from crossroads.rl.config import TrainConfig

assert math.isclose(XI_LOW[2], -0.075) and math.isclose(XI_HIGH[2], 0.225)
