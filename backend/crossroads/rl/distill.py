"""Distillation: a trained model's driving policy and value network refitted in another network layout.

    crossroads train distill models/apg.pt -o var/pooled/apg.pt --set participant_encoder=64

Why: a layout change that widening cannot bridge (``participant_encoder``: the participants pooled
through a shared encoder instead of read slot by slot) would otherwise mean training from scratch,
and the shipped models hold tens of thousands of CPU iterations. Instead the new networks are fitted
by supervised regression to the source's outputs, and a training run then starts from the result
(``--set init_from=OUT``) as from any model file.

The states: seeded sampling episodes of the source's own training distribution (the sampler of
:mod:`crossroads.rl.sampler` with the source's config and its policy driving, its rule-driven share
and standing-car copies included), and the states of the training model's rollouts from them with
the source's policy (every ``ROLLOUT_STRIDE``-th of its T steps), because the policy loss is
taken along those rollouts too. A tenth of the episodes is held out and the fit measured on it.

The targets: the driving policy's Gaussian (mean and log-std of z, before tanh) and the path value;
the adversary, whose layout does not change, is copied (widened if the new layout adds inputs).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from torch import Tensor

from crossroads.rl.buffer import Samples, to_batch
from crossroads.rl.checkpoint import load_networks
from crossroads.rl.config import TrainConfig, apply_overrides
from crossroads.rl.export import write_refitted_model
from crossroads.rl.idc_model import IDCModel
from crossroads.rl.neural_nets import Networks, networks_for, widen_first_layer
from crossroads.rl.sampler import EpisodeSampler, PathSet, WorkerSpec, policy_weights

ROLLOUT_STRIDE = 5  # (choice) every 5th rollout state: neighbours differ little, memory grows with each
HELD_OUT_SHARE = 0.1  # of the episodes
LOG_STD_WEIGHT = 0.1  # (choice) the spread matters less than the mean, which is the online action


@dataclass(frozen=True)
class DistillReport:
    """How well the new networks reproduce the source on the held-out states."""

    episodes: int
    states: int  # training states (rollout states included)
    held_out: int
    steps: int
    wall_time_s: float
    steer_rate_error: float  # mean |Δ mean action| [rad/s]
    jerk_error: float  # mean |Δ mean action| [m/s³]
    jerk_error_p99: float  # [m/s³]
    value_error: float  # mean |Δ v| / mean |v_source|

    def lines(self) -> list[str]:
        return [f"{self.episodes} episodes, {self.states} training states ({self.held_out} held out), "
                f"{self.steps} Adam steps, {self.wall_time_s:.0f} s",
                f"held out: mean |Δ action| {self.steer_rate_error:.4f} rad/s (steer rate), {self.jerk_error:.3f} m/s³ "
                f"(jerk; 99th percentile {self.jerk_error_p99:.3f}), mean |Δ value| {100 * self.value_error:.1f} % "
                f"of the mean value"]


def collect_episodes(config: TrainConfig, paths: PathSet, source: Networks, episodes: int) -> list[Samples]:
    """``episodes`` sampling episodes (rounds 0, 1, … of worker 0 under ``config.seed``) driven as in
    training, the source's policy driving where the rule controller does not."""
    sampler = EpisodeSampler(WorkerSpec(dataclasses.replace(config, rule_rounds=0), paths.keys), worker_id=0)
    weights = policy_weights(source.policy)
    return [sampler.round(r, weights) for r in range(episodes)]


def rollout_states(model: IDCModel, source: Networks, samples: Samples, horizon: int, chunk: int = 2048) -> Tensor:
    """The states s_0 and every ``ROLLOUT_STRIDE``-th state of the source policy's rollouts over
    ``horizon`` steps (ξ ≡ 0)."""
    out: list[Tensor] = []
    for start in range(0, len(samples.ego), chunk):
        part = samples.take(slice(start, start + chunk))

        def act(s: Tensor, i: int) -> Tensor:
            if i % ROLLOUT_STRIDE == 0:
                out.append(s)
            return source.policy.mean_action(s)

        with torch.no_grad():
            model.rollout(to_batch(part), act, None, horizon)
    return torch.cat(out)


def targets(source: Networks, states: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """(mean, log-std, value) of the source on ``states``."""
    with torch.no_grad():
        mean, log_std = source.policy.distribution(states)
        return mean, log_std, source.value(states)


def fit(student: Networks, states: Tensor, goal: tuple[Tensor, Tensor, Tensor], steps: int,
        batch_size: int, lr: float, generator: torch.Generator) -> None:
    """Adam with cosine annealing on the squared errors to the source's outputs (the value's
    normalised by the source's value spread, so both losses are of order one)."""
    mean, log_std, value = goal
    scale = value.std().clamp_min(1e-6)
    params = list(student.policy.parameters()) + list(student.value.parameters())
    optimiser = torch.optim.Adam(params, lr=lr)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, T_max=max(1, steps), eta_min=lr / 100)
    for _ in range(steps):
        idx = torch.randint(len(states), (batch_size,), generator=generator)
        m, ls = student.policy.distribution(states[idx])
        loss = ((m - mean[idx]) ** 2).mean() + LOG_STD_WEIGHT * ((ls - log_std[idx]) ** 2).mean()
        loss = loss + (((student.value(states[idx]) - value[idx]) / scale) ** 2).mean()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        schedule.step()


def held_out_errors(student: Networks, source: Networks, states: Tensor) -> tuple[float, float, float, float]:
    with torch.no_grad():
        diff = (student.policy.mean_action(states) - source.policy.mean_action(states)).abs()
        v_src = source.value(states)
        v_err = float((student.value(states) - v_src).abs().mean() / v_src.abs().mean().clamp_min(1e-6))
    return float(diff[:, 0].mean()), float(diff[:, 1].mean()), float(torch.quantile(diff[:, 1], 0.99)), v_err


def distill(source_path: Path, out: Path, overrides: dict[str, Any], episodes: int = 200, steps: int = 4000,
            batch_size: int = 512, lr: float = 1e-3, seed: int = 0) -> DistillReport:
    """Fit networks of the layout ``overrides`` name (on top of the source's config) to the source
    model ``source_path``; write them as a model file ``out`` with its card (module docstring)."""
    if episodes < 10:
        raise ValueError(f"episodes: at least 10 are needed (one tenth is held out), got {episodes}")
    if steps < 1:
        raise ValueError(f"steps: must be ≥ 1, got {steps}")
    started = time.monotonic()
    source, source_config = load_networks(source_path)
    config = dataclasses.replace(apply_overrides(source_config, overrides), seed=seed, init_from=None)
    if (config.path_preview, config.lead_input, config.participant_encoder) == (
            source_config.path_preview, source_config.lead_input, source_config.participant_encoder):
        raise ValueError("the overrides change no network layout (path_preview, lead_input, participant_encoder): "
                         "nothing to distill; start from the source itself with init_from")
    if source_config.path_preview and not config.path_preview:
        raise ValueError("path_preview: the source reads the path preview, so its states carry it; keep it on")
    torch.manual_seed(seed)
    student = networks_for(config)
    if source.adversary is not None and student.adversary is not None:
        student.adversary.load_state_dict(widen_first_layer(source.adversary.state_dict(), student.adversary))

    paths = PathSet.build(config.intersections, config.tasks)
    recorded = collect_episodes(dataclasses.replace(source_config, seed=seed), paths, source, episodes)
    held = max(1, round(HELD_OUT_SHARE * episodes))
    model = IDCModel(paths.tensors(dtype=torch.float32), preview=source_config.path_preview)
    train_states = rollout_states(model, source, Samples.concat(recorded[held:]), source_config.horizon)
    test_states = model.initial_states(to_batch(Samples.concat(recorded[:held])))
    generator = torch.Generator().manual_seed(seed)
    fit(student, train_states, targets(source, train_states), steps, batch_size, lr, generator)
    for net in student:
        if net is not None:
            net.eval()
    steer, jerk, jerk99, value = held_out_errors(student, source, test_states)
    report = DistillReport(episodes, len(train_states), len(test_states), steps, time.monotonic() - started,
                           steer, jerk, jerk99, value)
    write_model(out, config, student, source_path, report)
    return report


def write_model(out: Path, config: TrainConfig, nets: Networks, source: Path, report: DistillReport) -> None:
    """The distilled model file and its card (:func:`~crossroads.rl.export.write_refitted_model`),
    the card with the distillation's figures."""
    write_refitted_model(out, config, nets, source, [f"distilled from {source}: " + "; ".join(report.lines())],
                         report.wall_time_s, {"distillation": dataclasses.asdict(report)})
