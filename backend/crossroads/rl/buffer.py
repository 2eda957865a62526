"""The replay buffer of initial states (Algorithm 1 "Initialize buffer B").

A sampled state is what the model needs to roll out from it: the ego (8), the 16 other participants
(16 × 6, world frame, closest first per kind, padded), each one's route curvature 1/R (16), the
global index of the candidate path τ (into the run's padded path tensor, see
``sampler.PathSet``) and the speed mode (stop = True). The buffer is a fixed-capacity ring of numpy
arrays (float32); batches come out as :class:`StateBatch` of torch tensors. Its contents and
position are part of a checkpoint (:meth:`state_dict`), so a resumed run draws the same batches.

**(choice)** Danger-weighted draws. Each state carries a danger score: J_safe of the policy's own
plan from it (scored when it enters, rescored whenever a batch draws it). With ``danger_share`` > 0
that share of every batch is drawn from the states scoring above ``danger_threshold``, the rest
uniformly. Why: the states in the last seconds before a collision are a few per cent of what the
sampler sees, and with uniform draws a run of 6 000 iterations did not learn to stop behind a
standing car there, although its own model preferred braking (benchmarks/research/failure_modes.py); 300
policy steps on those states alone turned 20 collisions of 20 seeded runs into none. With
``danger_share = 0`` the draws are exactly the uniform ones of the paper.
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

    def take(self, rows: np.ndarray | slice) -> Samples:
        """The rows ``rows`` (an index array or a slice) of every field."""
        return Samples(*(getattr(self, f)[rows] for f in Samples._fields))


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
        self.danger = np.zeros(capacity, np.float32)  # J_safe of the policy's plan at the last scoring
        self.position = 0  # next slot written
        self.size = 0
        self.added = 0  # states ever added
        self.rng = np.random.default_rng(seed)

    def __len__(self) -> int:
        return self.size

    def add(self, samples: Samples, danger: np.ndarray | None = None) -> None:
        """Append ``samples`` (overwriting the oldest), with their danger scores (default 0)."""
        n = len(samples)
        if n == 0:
            return
        scores = np.zeros(n, np.float32) if danger is None else np.asarray(danger, np.float32).reshape(n)
        if n > self.capacity:  # only the newest fit
            samples = Samples(*(a[-self.capacity:] for a in samples))
            scores = scores[-self.capacity:]
            n = self.capacity
        idx = (self.position + np.arange(n)) % self.capacity
        for name in Samples._fields:
            getattr(self, name)[idx] = getattr(samples, name)
        self.danger[idx] = scores
        self.position = int((self.position + n) % self.capacity)
        self.size = min(self.capacity, self.size + n)
        self.added += len(samples)

    def draw(self, batch_size: int, danger_share: float = 0.0, danger_threshold: float = 1.0) -> np.ndarray:
        """Indices of a batch: uniform, except ``danger_share`` of them among the states scoring
        above ``danger_threshold`` (uniform alone while there are none)."""
        if self.size == 0:
            raise ValueError("the buffer is empty")
        n_hot = int(round(batch_size * danger_share))
        hot = np.flatnonzero(self.danger[: self.size] > danger_threshold) if n_hot else np.zeros(0, np.int64)
        if len(hot) == 0:
            n_hot = 0
        idx = self.rng.integers(0, self.size, size=batch_size - n_hot)
        if n_hot:
            idx = np.concatenate([idx, hot[self.rng.integers(0, len(hot), size=n_hot)]])
        return idx

    def batch(self, idx: np.ndarray, device: str | torch.device = "cpu") -> StateBatch:
        return to_batch(Samples(*(getattr(self, f)[idx] for f in Samples._fields)), device=device)

    def sample(self, batch_size: int, device: str | torch.device = "cpu", danger_share: float = 0.0,
               danger_threshold: float = 1.0) -> StateBatch:
        return self.batch(self.draw(batch_size, danger_share, danger_threshold), device)

    def rescore(self, idx: np.ndarray, danger: np.ndarray) -> None:
        """New danger scores for the states at ``idx`` (J_safe from the batch that drew them)."""
        self.danger[idx] = danger

    def state_dict(self) -> dict[str, Any]:
        n = self.size
        return {"capacity": self.capacity, "position": self.position, "size": n, "added": self.added,
                "rng": self.rng.bit_generator.state, "danger": self.danger[:n].copy(),
                **{f: getattr(self, f)[:n].copy() for f in Samples._fields}}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        if state["capacity"] != self.capacity:
            raise ValueError(f"buffer capacity {self.capacity} ≠ checkpoint's {state['capacity']}")
        n = state["size"]
        for f in Samples._fields:
            getattr(self, f)[:n] = state[f]
        self.danger[:n] = state.get("danger", 0.0)  # checkpoints from before the scores: all 0
        self.position, self.size, self.added = state["position"], n, state["added"]
        self.rng.bit_generator.state = state["rng"]
