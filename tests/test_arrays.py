"""The array namespaces: numpy with torch's sine and cosine gives torch's float32 numbers."""

from __future__ import annotations

import math

import numpy as np
import torch

from crossroads.arrays import NumpyOps, TorchOps, TorchTrigNumpyOps


def test_numpy_with_torchs_trig_gives_torchs_float32_numbers_bit_for_bit() -> None:
    angles = np.random.default_rng(7).uniform(-4 * math.pi, 4 * math.pi, 20_000).astype(np.float32)
    as_tensor = torch.from_numpy(angles)
    for name in ("sin", "cos"):
        ours = getattr(TorchTrigNumpyOps, name)(angles)
        assert isinstance(ours, np.ndarray) and ours.dtype == np.float32
        np.testing.assert_array_equal(ours, getattr(TorchOps, name)(as_tensor).numpy())
    # the reason for the class: numpy's own float32 sine and cosine are not torch's
    assert np.any(NumpyOps.cos(angles) != TorchOps.cos(as_tensor).numpy())
    # the wrap the state's normalisation uses agrees without help
    np.testing.assert_array_equal(TorchTrigNumpyOps.wrap(angles), TorchOps.wrap(as_tensor).numpy())


def test_numpy_with_torchs_trig_takes_views() -> None:
    grid = np.linspace(-3.0, 3.0, 12, dtype=np.float32).reshape(3, 4)
    np.testing.assert_array_equal(TorchTrigNumpyOps.sin(grid[:, 1]), torch.sin(torch.from_numpy(grid[:, 1].copy())).numpy())
