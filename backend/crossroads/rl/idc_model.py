"""The differentiable IDC model: T-step rollouts of f = (f_ego, f_other) in torch (SPEC §5-§6).

From a batch of initial states (:class:`~crossroads.rl.buffer.StateBatch`: ego 8, others 16×6, the
curvature 1/R of each other's route, a path index into padded candidate paths, the speed mode) the
model rolls out T steps::

    s_0 = [ego_0, x_track(ego_0, τ, mode), others_0]
    u_i = π_θ(s_i)          ξ_i = π_φ(s_i)  (APG)  or  None (DPG: ξ ≡ 0)
    l_i = utility(s_i, u_i)
    ego_{i+1} = ego_step(ego_i, u_i)        others_{i+1} = other_step(others_i, κ, ξ_i)
    s_{i+1} = [ego_{i+1}, tracking_error(ego_{i+1}, ref(ego_{i+1}, τ, mode)), others_{i+1}]
    φ_{i+1} = penalty(safety_constraints(s_{i+1}) ∪ road_constraints(s_{i+1}, ref))

and returns per sample J_track = Σ_{i<T} l_i and J_safe = Σ_{i<T} φ_{i+1}. Gradients flow through
the dynamics into u (θ) and ξ (φ); the reference point is data (``reference_points_torch`` computes
it without gradient, the ego's error against it is differentiable). **(choice)** κ of every
participant is held at its initial value over the horizon (the model has no routes).

How ξ enters the horizon (**(choice)**): ξ_v and ξ_φ propagate through f_other as printed (a
participant can speed up by up to 5.6 m/s or turn 0.6 rad off its route over the horizon: the
paper's over-speeding and rounding of Sec. V-C), while ξ_x, ξ_y displace each predicted position
from the participant's own (ξ_v, ξ_φ-driven) trajectory by at most ±0.8 m without carrying over to
the next step: a bounded position uncertainty, as the paper motivates ξ ("bounded random noise").
f_other as printed adds ξ_x, ξ_y at every step, so 25 steps of ±0.8 m move a participant up to
20 m in any direction; an APG trained so faced an adversary no plan could escape (median J_safe
117 with the ego standing) and learned to flee. That form lost and was removed (docs/tried/training.md,
"The adversary"; saved configs name it ``xi_positions="step"``).

The nominal floor (``nominal_floor``, **(choice)**, ``TrainConfig.nominal_floor``): with an
adversary, each safety constraint is taken as the worse (larger g) of the adversary's prediction
and the plain ξ ≡ 0 prediction of the same participant. ξ ≡ 0 lies inside the ξ ranges, so a
maximising adversary should never predict a milder scene than it; a half-trained one does.
Measured on an APG trained without it (docs/tried/training.md): its adversary had
learned ξ_v ≈ +0.22 m/s per step for nearly every participant — a standing queue ahead of the ego
is then predicted to drive off at 2.2 m/s² — and 1 s before 32 of its 37 collisions in 50 seeded
nominal left turns its mean ξ gave the policy's plan a lower J_safe than ξ ≡ 0 (median 3.9 against
47.4). The policy learned to drive into queues. The ego's states (the networks' inputs) still follow the adversary's scene; only the
constraints see both. DPG (ξ ≡ 0) is unchanged.

The braking floor (``braking_floor``, **(choice)**, ``TrainConfig.braking_floor``, off by default):
each safety constraint is also taken as the worse of the above and a prediction in which every
participant brakes at ``constants.OTHER_DECEL_MPS2`` to a stand (``sim.other.other_braking_step``,
the safety shield's second future). f_other keeps each speed, so over 2.5 s a car slowing into the
end of a queue is predicted to roll on: the receding-horizon optimum of the model
(benchmarks/research/probing.py) drove at 8.3 m/s into such a car (1 m/s and slowing, 14 m ahead) and
braked only when its constraint bound, too late; with the floor it braked in time and passed.

The stopping tail (``stopping_tail``, **(choice, not the paper's)**, ``TrainConfig.stopping_tail``,
0 = off): after the T steps the ego's last state is rolled on for that many steps of full braking
(Δa = −``JERK_MAX``, the wheel held: the shield's backup, ``idc.shield``) to its rest point, every
participant braking to a stand (the braking floor's future) to its own, and J_safe gets a terminal
penalty for every participant whose rest footprint lies in the ego's corridor short of the ego's
rest point plus the safety margin (:func:`stopping_intrusion`). Why: from 8.33 m/s full braking
(jerk-limited to −3 m/s²) takes ~3.3 s, longer than the 2.5 s horizon, so a plan can be free of
penalties over T steps and still end where no braking avoids the car standing ahead — the receding
horizon is not recursively feasible, and the trained policies drove into standing queues at the pass
profile's speed (docs/tried/training.md, "The stopping tail"). It does not depend on ξ and adds
no utility (J_track is unchanged).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import torch
from torch import Tensor

from crossroads.constants import EGO_LENGTH_M, EGO_WIDTH_M, JERK_MAX, OTHER_DECEL_MPS2
from crossroads.idc.constraints import SAFETY_MARGIN_M, penalty, road_constraints, safety_constraints
from crossroads.idc.state import N_OTHERS, PathTensors, Reference, preview_torch, reference_points_torch, tracking_error
from crossroads.idc.utility import utility
from crossroads.rl.buffer import StateBatch
from crossroads.sim.ego import ego_step
from crossroads.sim.other import other_braking_step, other_step

ActionFn = Callable[[Tensor, int], Tensor]  # (s_i [B, 108], i) → u_i [B, 2]
XiFn = Callable[[Tensor, int], Tensor]  # (s_i [B, 108], i) → ξ_i [B, 16, 4]


class Rollout(NamedTuple):
    """The model's costs of a batch, per sample."""

    j_track: Tensor  # (B,) Σ l
    j_safe: Tensor  # (B,) Σ φ (unweighted; J_π = J_track + ρ J_safe)
    s0: Tensor  # (B, 108) the initial states (input of v_w)
    overlap_m: Tensor  # (B,) deepest overlap of an ego circle with a participant's circle over the
    # horizon [m], the safety margin left out (> 0: the bodies' circles meet); no gradient


def assemble(ego: Tensor, track: Tensor, others: Tensor, preview: Tensor | None = None) -> Tensor:
    """s [B, 108] from ego [B, 8], x_track [B, 4], others [B, 16, 6]; [B, 120] with a path preview
    [B, 12] (``idc.state``)."""
    parts = [ego, track, others.reshape(others.shape[0], -1)]
    return torch.cat(parts if preview is None else parts + [preview], dim=-1)


class IDCModel:
    """The model f over a fixed set of candidate paths (padded, see ``idc.state.path_tensors``)."""

    def __init__(self, paths: PathTensors, nominal_floor: bool = False, braking_floor: bool = False,
                 preview: bool = False, stopping_tail: int = 0) -> None:
        if stopping_tail < 0:
            raise ValueError(f"stopping_tail must be ≥ 0 steps, got {stopping_tail}")
        self.paths = paths
        self.preview = preview  # states carry the path preview (networks with path_preview read it)
        self.nominal_floor = nominal_floor
        self.braking_floor = braking_floor
        self.stopping_tail = stopping_tail

    def track(self, ego: Tensor, path: Tensor, stop: Tensor) -> tuple[Tensor, Reference]:
        """(x_track [B, 4], the reference points) of ``ego`` against its path and mode."""
        ref = reference_points_torch(self.paths, ego[:, :2], path, stop)
        return tracking_error(ego, ref.x, ref.y, ref.heading, ref.v), ref

    def preview_of(self, ego: Tensor, ref: Reference, path: Tensor, stop: Tensor) -> Tensor | None:
        """The path preview [B, 12] of ``ego`` beyond its reference points, if this model has one."""
        return preview_torch(self.paths, ego, ref, path, stop) if self.preview else None

    def initial_states(self, batch: StateBatch) -> Tensor:
        """s_0 [B, 108] of a batch ([B, 120] with the preview)."""
        x_track, ref = self.track(batch.ego, batch.path, batch.stop)
        return assemble(batch.ego, x_track, batch.others, self.preview_of(batch.ego, ref, batch.path, batch.stop))

    def rollout(self, batch: StateBatch, act: ActionFn, disturb: XiFn | None, horizon: int) -> Rollout:
        """Roll the batch out ``horizon`` steps with ``act`` (and ``disturb``, or ξ ≡ 0)."""
        ego, others, kappa = batch.ego, batch.others, batch.kappa
        s = s0 = self.initial_states(batch)
        j_track = torch.zeros(ego.shape[0], dtype=ego.dtype, device=ego.device)
        j_safe = torch.zeros_like(j_track)
        overlap = torch.full_like(j_track, -torch.inf)
        course = others  # each participant's trajectory before this step's ξ_x, ξ_y
        nominal = others  # the ξ ≡ 0 prediction, for the nominal floor
        braking = others  # everyone braking to a stand, for the braking floor
        floor = self.nominal_floor and disturb is not None
        for i in range(horizon):
            u = act(s, i)
            xi = disturb(s, i) if disturb is not None else None
            l, _ = utility(s, u)
            ego = ego_step(ego, u)
            if xi is None:
                others = other_step(others, kappa, None)
            else:
                course = other_step(course, kappa, _without_positions(xi))
                others = _displaced(course, xi)
            x_track, ref = self.track(ego, batch.path, batch.stop)
            s = assemble(ego, x_track, others, self.preview_of(ego, ref, batch.path, batch.stop))
            g_safe = safety_constraints(s)
            if floor:
                nominal = other_step(nominal, kappa, None)
                g_safe = torch.maximum(g_safe, safety_constraints(assemble(ego, x_track, nominal)))
            if self.braking_floor or self.stopping_tail:  # the tail starts from this future's end
                braking = other_braking_step(braking, kappa, OTHER_DECEL_MPS2)
            if self.braking_floor:
                g_safe = torch.maximum(g_safe, safety_constraints(assemble(ego, x_track, braking)))
            g = torch.cat([g_safe, road_constraints(s, ref.x, ref.y, ref.heading)], dim=-1)
            j_track = j_track + l
            j_safe = j_safe + penalty(g)
            overlap = torch.maximum(overlap, g_safe.detach().amax(dim=-1) - SAFETY_MARGIN_M)
        if self.stopping_tail:
            j_safe = j_safe + self.tail_penalty(ego, braking, kappa)
        return Rollout(j_track, j_safe, s0, overlap)

    def tail_penalty(self, ego: Tensor, braking: Tensor, kappa: Tensor) -> Tensor:
        """The stopping tail's penalty (module docstring): ``ego`` [B, 8] brakes fully for
        ``stopping_tail`` steps, the participants ``braking`` [B, 16, 6] brake to a stand alongside,
        and :func:`stopping_intrusion` compares where each comes to rest."""
        full_braking = torch.zeros(ego.shape[0], 2, dtype=ego.dtype, device=ego.device)
        full_braking[:, 1] = -JERK_MAX
        rest = ego
        for _ in range(self.stopping_tail):
            rest = ego_step(rest, full_braking)
            braking = other_braking_step(braking, kappa, OTHER_DECEL_MPS2)
        intrusion = stopping_intrusion(ego, rest, braking)
        return (intrusion * intrusion).sum(dim=-1)


STOPPING_CORRIDOR_CLEARANCE_M = 0.5
"""[m] (choice) lateral clearance beyond the two half widths within which a participant's rest
footprint counts as in the ego's way (lanes are 3.5 m wide: a car centred in the next lane is 3.5 m
from the ego's centre line, beyond (2.0 + 1.8) / 2 + 0.5 = 2.4 m)."""


STOPPING_HEADING_COS = math.cos(math.radians(45.0))
"""(choice) Only participants heading within ±45° of the ego's count in the stopping tail: the cars and
cyclists it follows. A crossing participant or a pedestrian (braking to a stand in the prediction)
could otherwise be escaped by driving faster — past it by the end of the horizon, it lies behind the
ego and out of the corridor — and two runs trained so (500 iterations each) sped up on an empty
road from the shipped APG's 8.8–9.2 to 9.6–10.4 m/s; the horizon's own constraints keep those."""


def stopping_intrusion(ego: Tensor, rest: Tensor, others: Tensor) -> Tensor:
    """[B, 16] how far [m] the ego's braked rest footprint plus the safety margin reaches past the near
    end of each participant's rest footprint along the ego's way, 0 where it does not or where the
    participant is not in the way.

    Measured in the frame of ``ego`` [B, 8] (the horizon's last state, x along its heading): the
    ego's rest point ``rest`` [B, 8] lies x_e ahead, y_e to the side; a participant of ``others``
    [B, 16, 6] (at its own rest) is in the way when its centre lies ahead (x > 0), it heads the ego's
    way (``STOPPING_HEADING_COS``) and its lateral footprint overlaps the ego's within
    ``STOPPING_CORRIDOR_CLEARANCE_M``; then the intrusion is
    x_e + L_ego / 2 + margin − (x − its half extent along the ego's heading), clipped at 0.

    Why longitudinal and not the circles of :func:`safety_constraints`: where braking no longer stops
    short, the ego's circles pass through the other's in the prediction, and a circle penalty then
    falls as the ego drives on through (measured from 8.33 m/s coasting 24–38 m behind a standing car,
    the sum or the deepest intrusion over the tail: dJ_safe/dΔa negative at 5 of 7 gaps — more
    acceleration, less penalty; a run trained with it sped up to 10.2 m/s on an empty road). This
    intrusion only grows with the distance the ego travels, so its gradient always says stop sooner.
    The corridor test is data (no gradient flows through it)."""
    heading = ego[:, 4]
    c, s = torch.cos(heading)[:, None], torch.sin(heading)[:, None]  # [B, 1]
    ex, ey = ego[:, 0:1], ego[:, 1:2]
    rx, ry = rest[:, 0:1] - ex, rest[:, 1:2] - ey
    x_e, y_e = c * rx + s * ry, c * ry - s * rx  # [B, 1]
    ox, oy = others[..., 0] - ex, others[..., 1] - ey
    x_o, y_o = c * ox + s * oy, c * oy - s * ox  # [B, 16]
    rel = others[..., 3] - heading[:, None]
    cos_rel = torch.cos(rel)
    cos_r, sin_r = cos_rel.abs(), torch.sin(rel).abs()
    length, width = others[..., 4], others[..., 5]
    half_along = 0.5 * (length * cos_r + width * sin_r)
    half_across = 0.5 * (length * sin_r + width * cos_r)
    with torch.no_grad():
        in_way = ((x_o > 0.0) & (cos_rel > STOPPING_HEADING_COS)
                  & ((y_o - y_e).abs() < half_across + 0.5 * EGO_WIDTH_M + STOPPING_CORRIDOR_CLEARANCE_M))
    reach = x_e + 0.5 * EGO_LENGTH_M + SAFETY_MARGIN_M - (x_o - half_along)
    return torch.where(in_way, torch.relu(reach), torch.zeros_like(reach))


def _without_positions(xi: Tensor) -> Tensor:
    """ξ with ξ_x = ξ_y = 0 (the part of ξ that propagates over the horizon)."""
    return torch.cat([torch.zeros_like(xi[..., :2]), xi[..., 2:]], dim=-1)


def _displaced(others: Tensor, xi: Tensor) -> Tensor:
    """``others`` [B, 16, 6] with (ξ_x, ξ_y) added to their positions (not carried to the next step)."""
    return torch.cat([others[..., :2] + xi[..., :2], others[..., 2:]], dim=-1)


def policy_fns(policy: torch.nn.Module, adversary: torch.nn.Module | None, sample: bool,
               pre_squash: list[Tensor] | None = None) -> tuple[ActionFn, XiFn | None]:
    """The rollout's ``act`` / ``disturb`` from the networks: reparameterised draws when ``sample``,
    the squashed means otherwise. ``adversary=None`` (DPG) gives ξ ≡ 0. With ``pre_squash`` (a list),
    ``act`` appends the driving policy's pre-tanh means z [B, 2] of every step to it (the learner
    logs their saturated share); the draws are the same either way."""

    def act(s: Tensor, _: int) -> Tensor:
        mean, log_std = policy.distribution(s)  # type: ignore[operator]
        if pre_squash is not None:
            pre_squash.append(mean)
        if not sample:
            return policy.squash(mean)  # type: ignore[operator]
        eps = torch.randn(mean.shape, dtype=mean.dtype, device=mean.device)  # as policy.sample draws it
        return policy.squash(mean + torch.exp(log_std) * eps)  # type: ignore[operator]

    if adversary is None:
        return act, None

    def disturb(s: Tensor, _: int) -> Tensor:
        xi = adversary.sample(s) if sample else adversary.mean_action(s)  # type: ignore[operator]
        assert xi.shape[-2:] == (N_OTHERS, 4)
        return xi

    return act, disturb
