"""A tiny numpy / torch dispatch, so each model is written once for both backends.

``ops(x)`` returns the namespace for the backend of ``x``: :data:`NUMPY` for numpy arrays, Python
numbers and lists, :data:`TORCH` for ``torch.Tensor``. Torch is only imported when a tensor is
seen (detected by its type's module), so numpy-only users never pay for importing it.

Only the handful of functions the models need are provided; each has the same meaning in both
namespaces (``axis`` is ``dim`` for torch). Torch versions are differentiable wherever the maths is.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def is_torch(x: Any) -> bool:
    """True for a ``torch.Tensor`` (without importing torch)."""
    return type(x).__module__.startswith("torch")


class _Numpy:
    name = "numpy"
    sin, cos, sqrt, abs, arctan2 = np.sin, np.cos, np.sqrt, np.abs, np.arctan2
    minimum, maximum, where = np.minimum, np.maximum, np.where

    @staticmethod
    def asarray(x: Any, like: Any = None) -> np.ndarray:
        return np.asarray(x, dtype=np.float64)

    @staticmethod
    def clip(x: Any, lo: Any, hi: Any) -> np.ndarray:
        return np.clip(x, lo, hi)

    @staticmethod
    def stack(xs: list, axis: int = -1) -> np.ndarray:
        return np.stack(np.broadcast_arrays(*xs), axis=axis)

    @staticmethod
    def concat(xs: list, axis: int = -1) -> np.ndarray:
        return np.concatenate(xs, axis=axis)

    @staticmethod
    def sum(x: Any, axis: int = -1) -> np.ndarray:
        return np.sum(x, axis=axis)

    @staticmethod
    def wrap(angle: Any) -> np.ndarray:
        """Angle wrapped into [-π, π)."""
        return np.mod(np.asarray(angle) + math.pi, 2.0 * math.pi) - math.pi

    @staticmethod
    def zeros_like(x: Any) -> np.ndarray:
        return np.zeros_like(x)


class _Torch:
    name = "torch"

    def __init__(self) -> None:
        import torch

        self.torch = torch
        self.sin, self.cos, self.sqrt, self.abs = torch.sin, torch.cos, torch.sqrt, torch.abs
        self.arctan2, self.minimum, self.maximum = torch.atan2, torch.minimum, torch.maximum
        self.zeros_like = torch.zeros_like

    def asarray(self, x: Any, like: Any = None) -> Any:
        if is_torch(x):
            return x if like is None else x.to(dtype=like.dtype, device=like.device)
        if like is None:
            return self.torch.as_tensor(np.asarray(x, dtype=np.float64))
        return self.torch.as_tensor(np.asarray(x, dtype=np.float64), dtype=like.dtype, device=like.device)

    def clip(self, x: Any, lo: Any, hi: Any) -> Any:
        return self.torch.clamp(x, lo, hi)

    def where(self, cond: Any, a: Any, b: Any) -> Any:
        return self.torch.where(cond, a, b)

    def stack(self, xs: list, axis: int = -1) -> Any:
        return self.torch.stack(self.torch.broadcast_tensors(*xs), dim=axis)

    def concat(self, xs: list, axis: int = -1) -> Any:
        return self.torch.cat(xs, dim=axis)

    def sum(self, x: Any, axis: int = -1) -> Any:
        return self.torch.sum(x, dim=axis)

    def wrap(self, angle: Any) -> Any:
        """Angle wrapped into [-π, π)."""
        return self.torch.remainder(angle + math.pi, 2.0 * math.pi) - math.pi


NUMPY = _Numpy()
_TORCH: _Torch | None = None


def torch_ops() -> _Torch:
    global _TORCH
    if _TORCH is None:
        _TORCH = _Torch()
    return _TORCH


def ops(*xs: Any) -> Any:
    """The namespace for the backend of the inputs: torch if any of them is a tensor, else numpy."""
    return torch_ops() if any(is_torch(x) for x in xs) else NUMPY


def as_backend(x: Any, like: Any) -> Any:
    """``x`` converted to the backend (and, for torch, dtype/device) of ``like``."""
    if is_torch(like):
        return torch_ops().asarray(x, like=like)
    return np.asarray(x, dtype=np.float64)
