"""APG / DPG training, Algorithm 1 of the paper, top to bottom: ``train(config) -> run_dir``.

Per iteration k (0-based; "iteration" in logs and checkpoints counts iterations done = k + 1):

* Sampling: rounds of worker episodes (``rl.sampler``) fill the ring buffer so that, before
  iteration k, at least ``learning_starts + samples_per_iteration · k`` states have entered it.
  One round is always in flight; it was issued with the policy weights of its issue time.
* Optimising (``rl.learner``): a batch of ``batch_size`` states (a ``danger_share`` of them among
  the states whose last J_safe exceeded ``danger_threshold``, see ``rl.buffer``), the value step,
  the policy step and, when k % m == 0 (APG), the adversary step; the batch's J_safe rescore its
  states. New states are scored by the current policy's plan as they enter the buffer.
* Every ``log_every`` iterations (and at the end): a CSV/TensorBoard row with the window's mean
  J_v, J_track, J_safe, J_π, TAR of the current policy (``rl.evaluate``) and iterations/s.
* Every ``checkpoint_every`` iterations (and at the end): a checkpoint (``rl.checkpoint``);
  ``train(config, resume=True)`` continues from the newest one exactly as if uninterrupted
  (given the same number of workers: a round's episodes depend on the worker ids).

Run directory: ``config.json``, ``metrics.csv``, ``tb/`` (TensorBoard, if installed),
``checkpoints/``.
"""

from __future__ import annotations

import dataclasses
import random
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from crossroads.rl.buffer import ReplayBuffer, to_batch
from crossroads.rl.checkpoint import load_checkpoint, rng_states, save_checkpoint, set_rng_states
from crossroads.rl.config import TrainConfig, save_config
from crossroads.rl.evaluate import evaluate_tar
from crossroads.rl.learner import Learner
from crossroads.rl.logging import MetricsLogger, Progress
from crossroads.rl.idc_model import IDCModel
from crossroads.rl.neural_nets import widen_first_layer
from crossroads.rl.sampler import PathSet, PolicyWeights, make_sampler, policy_weights

RUNTIME_FIELDS = ("workers", "ray_address", "device", "torch_threads", "progress", "tensorboard")
"""Fields a resumed run may change (they do not change the maths; `workers` changes the episodes)."""


class RunExistsError(FileExistsError):
    """The run directory already holds a run and ``resume`` was not asked for."""


def train(config: TrainConfig, *, resume: bool = False) -> Path:
    """Train per ``config``; returns the run directory. ``resume``: continue its newest checkpoint."""
    run_dir = config.directory
    checkpoint: dict[str, Any] | None = None
    if resume:
        checkpoint = load_checkpoint(run_dir)
        saved = TrainConfig.from_json(checkpoint["config"])
        config = dataclasses.replace(saved, **{f: getattr(config, f) for f in RUNTIME_FIELDS})
    elif (run_dir / "checkpoints").exists():
        raise RunExistsError(f"{run_dir} already holds a run; resume it or choose another --out/run_name")
    run_dir.mkdir(parents=True, exist_ok=True)
    save_config(config, run_dir / "config.json")
    if config.torch_threads > 0:
        torch.set_num_threads(config.torch_threads)
    device = torch.device(config.device)

    # --- seeding (the one place) --------------------------------------------------------------------
    random.seed(config.seed)
    np.random.seed(config.seed % 2**32)
    torch.manual_seed(config.seed)
    buffer_seed, = np.random.SeedSequence(config.seed).spawn(1)
    # worlds: round r of worker w draws from default_rng([seed, w, r]) (rl.sampler); TAR: tar_seed + r

    paths = PathSet.build(config.intersections, config.tasks)
    model = IDCModel(paths.tensors(device=device), nominal_floor=config.nominal_floor,
                     braking_floor=config.braking_floor, preview=config.path_preview,
                     stopping_tail=config.stopping_tail)
    learner = Learner(config, model, device)
    buffer = ReplayBuffer(config.buffer_size, buffer_seed)
    start = 0
    next_round = 0
    pending: tuple[int, PolicyWeights | None] | None = None
    window = _Window()
    if checkpoint is not None:
        if tuple(map(tuple, checkpoint["path_keys"])) != paths.keys:
            raise ValueError("the candidate paths changed since the checkpoint (intersections or planner)")
        learner.load_state_dict(checkpoint["learner"])
        buffer.load_state_dict(checkpoint["buffer"])
        set_rng_states(checkpoint["rng"])
        start = checkpoint["iteration"]
        next_round = checkpoint["sampler"]["next_round"]
        pending = checkpoint["sampler"]["pending"]
        window = _Window.restore(checkpoint["window"])

    elif config.init_from is not None:
        warm_start(learner, config.init_from)

    logger = MetricsLogger(run_dir, resume_iteration=start if checkpoint else None,
                           tensorboard=config.tensorboard)
    sampler = make_sampler(config, paths.keys)
    progress = Progress(config.iterations, start, enabled=config.progress)

    def issue() -> None:
        nonlocal next_round, pending
        weights = policy_weights(learner.nets.policy) if next_round >= config.rule_rounds else None
        sampler.submit(next_round, weights)
        pending = (next_round, weights)
        next_round += 1

    try:
        if pending is not None:  # the round in flight at the checkpoint, with its own weights
            sampler.submit(*pending)
        else:
            issue()
        window.started = time.monotonic()
        for k in range(start, config.iterations):
            need = config.learning_starts + config.samples_per_iteration * k
            while buffer.added < need:
                fresh = sampler.collect()
                scores = learner.danger(to_batch(fresh, device=device)) if config.danger_share > 0 else None
                buffer.add(fresh, scores)
                issue()
            drawn = buffer.draw(config.batch_size, config.danger_share, config.danger_threshold)
            losses = learner.update(buffer.batch(drawn, device), k)
            if config.danger_share > 0:
                buffer.rescore(drawn, losses.j_safe_per_state)
            window.add(losses)
            done = k + 1
            progress.update(1, f"J_pi {losses.j_pi:.3g}")
            if done % config.log_every == 0 or done == config.iterations:
                row = window.row(done)
                row.update({f"charts/{_tar_name(key)}": v for key, v in evaluate_tar(learner.nets, config).items()})
                lrs = learner.lrs()
                row.update({"charts/lr_policy": lrs["policy"], "charts/lr_value": lrs["value"],
                            "charts/lr_adversary": lrs.get("adversary", float("nan")),
                            "buffer/size": len(buffer), "buffer/added": buffer.added})
                logger.log(row)
                window = _Window(started=time.monotonic())
            if done % config.checkpoint_every == 0 or done == config.iterations:
                save_checkpoint(run_dir, done, {
                    "config": config.to_json(), "learner": learner.state_dict(), "buffer": buffer.state_dict(),
                    "rng": rng_states(), "path_keys": [list(key) for key in paths.keys],
                    "sampler": {"next_round": next_round, "pending": pending},
                    "window": window.state(),
                })
    finally:
        progress.close()
        sampler.close()
        logger.close()
    return run_dir


def _tar_name(key: str) -> str:
    return {"tar": "TAR", "tar_std": "TAR_std", "tar_steps": "TAR_steps", "tar_collisions": "TAR_collisions",
            "tar_off_road": "TAR_off_road", "tar_passed": "TAR_passed"}[key]


@dataclasses.dataclass
class _Window:
    """Running sums of the losses since the last log row."""

    n: int = 0
    j_v: float = 0.0
    j_track: float = 0.0
    j_safe: float = 0.0
    j_pi: float = 0.0
    saturated_share: float = 0.0
    elapsed: float = 0.0  # [s] spent in this window before a resume
    started: float = 0.0  # time.monotonic() at the window's (re)start; not saved

    def add(self, losses: Any) -> None:
        self.n += 1
        self.j_v += losses.j_v
        self.j_track += losses.j_track
        self.j_safe += losses.j_safe
        self.j_pi += losses.j_pi
        self.saturated_share += losses.saturated_share

    def row(self, iteration: int) -> dict[str, float]:
        n = max(self.n, 1)
        seconds = self.elapsed + time.monotonic() - self.started
        return {"iteration": iteration, "losses/J_v": self.j_v / n, "losses/J_track": self.j_track / n,
                "losses/J_safe": self.j_safe / n, "losses/J_pi": self.j_pi / n,
                "charts/saturated_share": self.saturated_share / n,
                "charts/iterations_per_s": self.n / max(seconds, 1e-9), "time/elapsed_s": seconds}

    def state(self) -> dict[str, float]:
        return {"n": self.n, "j_v": self.j_v, "j_track": self.j_track, "j_safe": self.j_safe,
                "j_pi": self.j_pi, "saturated_share": self.saturated_share,
                "elapsed": self.elapsed + time.monotonic() - self.started}

    @classmethod
    def restore(cls, state: dict[str, float]) -> _Window:
        """The window of a checkpoint's :meth:`state`; sums of metrics since dropped (a checkpoint
        written while the saturation penalty existed holds its sum) are ignored."""
        known = {f.name for f in dataclasses.fields(cls)}
        return cls(**{key: value for key, value in state.items() if key in known})


def warm_start(learner: Learner, source: Path) -> None:
    """Load the networks of ``source`` (model file or checkpoint) into a fresh learner; networks
    trained without the path preview start a run with it unchanged (``widen_first_layer``)."""
    networks = load_checkpoint(source)["learner"]
    for name, net in zip(("policy", "value", "adversary"), learner.nets, strict=True):
        if net is not None and networks.get(name) is not None:
            net.load_state_dict(widen_first_layer(networks[name], net))

