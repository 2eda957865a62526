"""Training of the IDC networks by APG / DPG (SPEC §6; paper Sec. III-B, Algorithm 1, Sec. V-A).

* :mod:`~crossroads.rl.config` — :class:`TrainConfig`, every field with unit and source;
* :mod:`~crossroads.rl.experiments` — named recipes on top of the paper's configuration;
* :mod:`~crossroads.rl.neural_nets` — π_θ (driving policy), π_φ (adversary), v_w (value);
* :mod:`~crossroads.rl.idc_model` — the differentiable T-step model f in torch (J_track, J_safe);
* :mod:`~crossroads.rl.buffer` — the ring buffer of sampled states, NamedTuple batches;
* :mod:`~crossroads.rl.sampler` — state sampling in SUMO worlds (processes or Ray actors);
* :mod:`~crossroads.rl.learner` — value / policy / adversary steps;
* :mod:`~crossroads.rl.evaluate` — TAR in real SUMO runs;
* :mod:`~crossroads.rl.train` — :func:`train` (Algorithm 1), checkpoints, logs;
* :mod:`~crossroads.rl.cli` — ``crossroads train ...`` and ``crossroads train plot``.

Imports are lazy: ``import crossroads.rl`` does not import torch.
"""

from __future__ import annotations

from typing import Any

__all__ = ["TrainConfig", "train", "load_networks"]


def __getattr__(name: str) -> Any:
    if name == "TrainConfig":
        from crossroads.rl.config import TrainConfig

        return TrainConfig
    if name == "train":
        from crossroads.rl.train import train

        return train
    if name == "load_networks":
        from crossroads.rl.checkpoint import load_networks

        return load_networks
    raise AttributeError(name)
