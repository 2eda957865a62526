"""The replay buffer of initial states (Algorithm 1 "Initialize buffer B").

A sampled state is what the model needs to roll out from it: the ego (8), the 16 other participants
(16 × 6, world frame, closest first per kind, padded), each one's route curvature 1/R (16), the
global index of the candidate path τ (into the run's padded path tensor, see
``sampler.PathSet``) and the speed mode (stop = True). The buffer is a fixed-capacity ring of numpy
arrays (float32); batches come out as :class:`StateBatch` of torch tensors. Its contents and
position are part of a checkpoint (:meth:`state_dict`), so a resumed run draws the same batches.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import torch
from torch import Tensor

from crossroads.constants import EGO_STATE_DIM, OTHER_STATE_DIM
from crossroads.idc.state import N_OTHERS


class StateBatch(NamedTuple):
    """A batch of initial states for the model (torch)."""

    ego: Tensor  # (B, 8)
    others: Tensor  # (B, 16, 6)
    kappa: Tensor  # (B, 16) [1/m]
    path: Tensor  # (B,) long: index into the padded path tensor
    stop: Tensor  # (B,) bool: stop-mode speed profile


class Samples(NamedTuple):
    """Sampled states as numpy arrays (what workers send), one row per environment step."""

    ego: np.ndarray  # (n, 8)
    others: np.ndarray  # (n, 16, 6)
    kappa: np.ndarray  # (n, 16)
    path: np.ndarray  # (n,) int64
    stop: np.ndarray  # (n,) bool

    @staticmethod
    def empty() -> Samples:
        return Samples(np.zeros((0, EGO_STATE_DIM), np.float32),
                       np.zeros((0, N_OTHERS, OTHER_STATE_DIM), np.float32),
                       np.zeros((0, N_OTHERS), np.float32), np.zeros(0, np.int64), np.zeros(0, bool))

    @staticmethod
    def concat(parts: list[Samples]) -> Samples:
        if not parts:
            return Samples.empty()
        return Samples(*(np.concatenate([getattr(p, f) for p in parts]) for f in Samples._fields))

    def __len__(self) -> int:  # type: ignore[override]
        return len(self.path)


def to_batch(samples: Samples, dtype: torch.dtype = torch.float32, device: str | torch.device = "cpu"
             ) -> StateBatch:
    """Numpy samples → a :class:`StateBatch` of tensors."""
    f = lambda a: torch.as_tensor(np.asarray(a), dtype=dtype, device=device)  # noqa: E731
    return StateBatch(f(samples.ego), f(samples.others), f(samples.kappa),
                      torch.as_tensor(samples.path, dtype=torch.long, device=device),
                      torch.as_tensor(samples.stop, dtype=torch.bool, device=device))


class ReplayBuffer:
    """Ring buffer of sampled states; :meth:`sample` draws uniformly with its own numpy generator."""

    def __init__(self, capacity: int, seed: int | np.random.SeedSequence = 0) -> None:
        self.capacity = capacity
        self.ego = np.zeros((capacity, EGO_STATE_DIM), np.float32)
        self.others = np.zeros((capacity, N_OTHERS, OTHER_STATE_DIM), np.float32)
        self.kappa = np.zeros((capacity, N_OTHERS), np.float32)
        self.path = np.zeros(capacity, np.int64)
        self.stop = np.zeros(capacity, bool)
        self.position = 0  # next slot written
        self.size = 0
        self.added = 0  # states ever added
        self.rng = np.random.default_rng(seed)

    def __len__(self) -> int:
        return self.size

    def add(self, samples: Samples) -> None:
        n = len(samples)
        if n == 0:
            return
        if n > self.capacity:  # only the newest fit
            samples = Samples(*(a[-self.capacity:] for a in samples))
            n = self.capacity
        idx = (self.position + np.arange(n)) % self.capacity
        for name in Samples._fields:
            getattr(self, name)[idx] = getattr(samples, name)
        self.position = int((self.position + n) % self.capacity)
        self.size = min(self.capacity, self.size + n)
        self.added += len(samples)

    def sample(self, batch_size: int, device: str | torch.device = "cpu") -> StateBatch:
        if self.size == 0:
            raise ValueError("the buffer is empty")
        idx = self.rng.integers(0, self.size, size=batch_size)
        return to_batch(Samples(*(getattr(self, f)[idx] for f in Samples._fields)), device=device)

    def state_dict(self) -> dict[str, Any]:
        n = self.size
        return {"capacity": self.capacity, "position": self.position, "size": n, "added": self.added,
                "rng": self.rng.bit_generator.state,
                **{f: getattr(self, f)[:n].copy() for f in Samples._fields}}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        if state["capacity"] != self.capacity:
            raise ValueError(f"buffer capacity {self.capacity} ≠ checkpoint's {state['capacity']}")
        n = state["size"]
        for f in Samples._fields:
            getattr(self, f)[:n] = state[f]
        self.position, self.size, self.added = state["position"], n, state["added"]
        self.rng.bit_generator.state = state["rng"]
