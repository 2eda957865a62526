"""A minimal array namespace so one formula serves numpy arrays and torch tensors.

The maths of the driving world (``sim/ego.py``, ``sim/other.py``, ``idc/*``) is written once against
the handful of operations below. :func:`ops` picks the numpy or the torch implementation from the
inputs: torch when any input is a ``torch.Tensor``, numpy otherwise. torch is never imported by this
module: a tensor can only exist if the caller already imported torch, so numpy-only users (the
online controller, the world) do not pay torch's import time.

All functions broadcast over leading dimensions; ``axis``/``dim`` follow numpy's meaning. The torch
versions are differentiable wherever the operation is (clip/where pass gradients to the selected
branch, argmin is index selection).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np

Array = Any  # numpy.ndarray | torch.Tensor; kept loose on purpose (torch is optional at import time)


def is_torch(x: object) -> bool:
    """True when ``x`` is a torch tensor (without importing torch)."""
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(x, torch.Tensor)


class NumpyOps:
    """The namespace for numpy arrays (and Python scalars)."""

    name = "numpy"

    @staticmethod
    def asarray(x: Any, like: Array | None = None) -> np.ndarray:
        """``x`` as a float array: the dtype of ``like`` when that is a floating array, else a
        floating ``x`` is kept as is and anything else becomes float64."""
        if isinstance(like, np.ndarray) and like.dtype.kind == "f":
            return np.asarray(x, dtype=like.dtype)
        if isinstance(x, np.ndarray) and x.dtype.kind == "f":
            return x
        return np.asarray(x, dtype=np.float64)

    sin = staticmethod(np.sin)
    cos = staticmethod(np.cos)
    sqrt = staticmethod(np.sqrt)
    abs = staticmethod(np.abs)
    atan2 = staticmethod(np.arctan2)
    where = staticmethod(np.where)
    maximum = staticmethod(np.maximum)
    minimum = staticmethod(np.minimum)
    broadcast_to = staticmethod(np.broadcast_to)

    @staticmethod
    def clip(x: Array, lo: Any = None, hi: Any = None) -> np.ndarray:
        return np.clip(x, lo, hi)

    @staticmethod
    def stack(xs: Sequence[Array], axis: int = -1) -> np.ndarray:
        return np.stack(np.broadcast_arrays(*xs), axis=axis)

    @staticmethod
    def concat(xs: Sequence[Array], axis: int = -1) -> np.ndarray:
        return np.concatenate(xs, axis=axis)

    @staticmethod
    def sum(x: Array, axis: int | None = None) -> np.ndarray:
        return np.sum(x, axis=axis)

    @staticmethod
    def argmin(x: Array, axis: int = -1) -> np.ndarray:
        return np.argmin(x, axis=axis)

    @staticmethod
    def take_along(x: Array, idx: Array, axis: int) -> np.ndarray:
        return np.take_along_axis(x, idx, axis=axis)

    @staticmethod
    def zeros_like(x: Array) -> np.ndarray:
        return np.zeros_like(x)

    @staticmethod
    def wrap(angle_rad: Array) -> np.ndarray:
        """Angles wrapped into [−π, π) (the formula of :func:`crossroads.geometry.wrap_angle`)."""
        return np.mod(angle_rad + np.pi, 2.0 * np.pi) - np.pi


class TorchTrigNumpyOps(NumpyOps):
    """numpy, but ``sin`` and ``cos`` through torch's kernels: float32 numpy arithmetic then gives
    the numbers torch gives on the same float32 data, bit for bit (numpy's own float32 sin and cos
    differ from torch's in the last bit for about 6 % of angles; the elementwise arithmetic, the
    wrap and the stacking agree exactly). The online decision normalises its few states this way:
    numpy's per-call overhead is a fraction of torch's on arrays of a few hundred values, and the
    policies still see exactly the inputs they were trained and measured on."""

    name = "numpy+torch-trig"

    @staticmethod
    def sin(x: Array) -> np.ndarray:
        import torch

        return torch.sin(torch.from_numpy(np.ascontiguousarray(x))).numpy()

    @staticmethod
    def cos(x: Array) -> np.ndarray:
        import torch

        return torch.cos(torch.from_numpy(np.ascontiguousarray(x))).numpy()


class TorchOps:
    """The namespace for torch tensors (numpy inputs mixed in are converted to the tensor's dtype)."""

    name = "torch"

    @staticmethod
    def asarray(x: Any, like: Array | None = None) -> Any:
        """``x`` as a floating tensor.

        With a tensor ``like``: ``x`` converted to its dtype and device (a tensor by ``.to``, so its
        gradient still flows; ``x is like`` returns it unchanged). Otherwise a floating tensor is
        kept as is, a numpy array keeps its float dtype (float64 for other data), and anything
        else gets torch's default dtype.
        """
        import torch

        if isinstance(like, torch.Tensor) and like.dtype.is_floating_point:
            if isinstance(x, torch.Tensor):
                return x.to(dtype=like.dtype, device=like.device)
            return torch.as_tensor(np.asarray(x, dtype=np.float64), dtype=like.dtype, device=like.device)
        if isinstance(x, torch.Tensor):
            return x if x.dtype.is_floating_point else x.to(torch.get_default_dtype())
        if isinstance(x, np.ndarray):
            return torch.as_tensor(x if x.dtype.kind == "f" else x.astype(np.float64))
        return torch.as_tensor(x, dtype=torch.get_default_dtype())

    @staticmethod
    def sin(x: Any) -> Any:
        import torch

        return torch.sin(x)

    @staticmethod
    def cos(x: Any) -> Any:
        import torch

        return torch.cos(x)

    @staticmethod
    def sqrt(x: Any) -> Any:
        import torch

        return torch.sqrt(x)

    @staticmethod
    def abs(x: Any) -> Any:
        import torch

        return torch.abs(x)

    @staticmethod
    def atan2(y: Any, x: Any) -> Any:
        import torch

        return torch.atan2(y, x)

    @staticmethod
    def where(cond: Any, a: Any, b: Any) -> Any:
        import torch

        return torch.where(cond, a, b)

    @staticmethod
    def maximum(a: Any, b: Any) -> Any:
        import torch

        return torch.maximum(a, b)

    @staticmethod
    def minimum(a: Any, b: Any) -> Any:
        import torch

        return torch.minimum(a, b)

    @staticmethod
    def broadcast_to(x: Any, shape: Sequence[int]) -> Any:
        import torch

        return torch.broadcast_to(x, tuple(shape))

    @staticmethod
    def clip(x: Any, lo: Any = None, hi: Any = None) -> Any:
        import torch

        return torch.clamp(x, min=lo, max=hi)

    @staticmethod
    def stack(xs: Sequence[Any], axis: int = -1) -> Any:
        import torch

        return torch.stack(torch.broadcast_tensors(*xs), dim=axis)

    @staticmethod
    def concat(xs: Sequence[Any], axis: int = -1) -> Any:
        import torch

        return torch.cat(list(xs), dim=axis)

    @staticmethod
    def sum(x: Any, axis: int | None = None) -> Any:
        import torch

        return torch.sum(x) if axis is None else torch.sum(x, dim=axis)

    @staticmethod
    def argmin(x: Any, axis: int = -1) -> Any:
        import torch

        return torch.argmin(x, dim=axis)

    @staticmethod
    def take_along(x: Any, idx: Any, axis: int) -> Any:
        """``idx`` must have ``x``'s shape but along ``axis`` (no broadcasting): ``torch.gather``,
        which ONNX exports, where ``take_along_dim`` does not export."""
        import torch

        return torch.gather(x, axis, idx)

    @staticmethod
    def zeros_like(x: Any) -> Any:
        import torch

        return torch.zeros_like(x)

    @staticmethod
    def wrap(angle_rad: Any) -> Any:
        """Angles wrapped into [−π, π) (gradient 1 everywhere but at the jump)."""
        import torch

        return torch.remainder(angle_rad + math.pi, 2.0 * math.pi) - math.pi


class ScalarOps:
    """Plain Python floats: the same formulas for one state, without numpy's per-call overhead
    (the online loop steps one ego every 0.1 s; tiny arrays cost more than the arithmetic)."""

    name = "scalar"
    sin = staticmethod(math.sin)
    cos = staticmethod(math.cos)

    @staticmethod
    def clip(x: float, lo: float | None = None, hi: float | None = None) -> float:
        if lo is not None and x < lo:
            return lo
        if hi is not None and x > hi:
            return hi
        return x


Ops = type[NumpyOps] | type[TorchOps]


def ops(*arrays: object) -> Ops:
    """The namespace for these inputs: torch if any of them is a tensor, numpy otherwise.

    ``None`` entries (an optional argument left out) are ignored.
    """
    return TorchOps if any(is_torch(a) for a in arrays) else NumpyOps
