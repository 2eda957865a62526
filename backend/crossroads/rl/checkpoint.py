"""Checkpoints: everything a run needs to continue exactly, in one ``torch.save`` file.

Contents: format version, the config (JSON), the iteration (iterations done), the learner's networks,
optimisers and schedulers, RNG states (python, numpy global, torch), the replay buffer (contents,
position, generator), the sampler's bookkeeping (next round, the round in flight and the policy
weights it was issued with), the path keys, and the running metric sums of the current log window.
``checkpoints/ckpt_<iteration>.pt`` and ``checkpoints/last.pt`` (a copy of the newest).

:func:`load_networks` rebuilds the networks of a checkpoint for inference (``crossroads.rl.load_policy``).
"""

from __future__ import annotations

import random
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import torch

from crossroads.rl.config import TrainConfig
from crossroads.rl.networks import Networks, networks_for

FORMAT = 1
LAST = "last.pt"


def rng_states() -> dict[str, Any]:
    return {"python": random.getstate(), "numpy": np.random.get_state(), "torch": torch.get_rng_state()}


def set_rng_states(state: dict[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    torch.set_rng_state(state["torch"])


def save_checkpoint(run_dir: Path, iteration: int, payload: dict[str, Any]) -> Path:
    folder = Path(run_dir) / "checkpoints"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"ckpt_{iteration:08d}.pt"
    tmp = path.with_suffix(".tmp")
    torch.save({"format": FORMAT, "iteration": iteration, **payload}, tmp)
    tmp.replace(path)
    shutil.copyfile(path, folder / LAST)
    return path


def find_checkpoint(path: Path) -> Path:
    """A checkpoint file, or the newest of a run directory / its checkpoints folder."""
    path = Path(path)
    if path.is_file():
        return path
    for folder in (path / "checkpoints", path):
        if (folder / LAST).is_file():
            return folder / LAST
    raise FileNotFoundError(f"no checkpoint at {path}")


def load_checkpoint(path: Path, map_location: str | torch.device = "cpu") -> dict[str, Any]:
    data = torch.load(find_checkpoint(path), map_location=map_location, weights_only=False)
    if data.get("format") != FORMAT:
        raise ValueError(f"{path}: checkpoint format {data.get('format')!r}, expected {FORMAT}")
    return data


def load_networks(path: Path, device: str | torch.device = "cpu") -> tuple[Networks, TrainConfig]:
    """The networks of a checkpoint (eval mode) and its config."""
    data = load_checkpoint(path, device)
    config = TrainConfig.from_json(data["config"])
    nets = networks_for(config, device)
    learner = data["learner"]
    nets.policy.load_state_dict(learner["policy"])
    nets.value.load_state_dict(learner["value"])
    if nets.adversary is not None:
        nets.adversary.load_state_dict(learner["adversary"])
    for net in nets:
        if net is not None:
            net.eval()
    return nets, config
