"""Helpers of the RL tests: batches of states near candidate paths."""

from __future__ import annotations

import numpy as np
import torch

from crossroads.constants import EGO_LENGTH_M, EGO_WIDTH_M
from crossroads.rl.buffer import StateBatch
from crossroads.rl.sampler import PathSet

INTERSECTION = "a_single_lane"


def make_batch(path_set: PathSet, n: int, seed: int = 0, dtype: torch.dtype = torch.float32) -> StateBatch:
    """States near their paths: ego on a random path point with small errors; others around the ego
    (some close enough that safety constraints bind), with curvatures and random modes."""
    rng = np.random.default_rng(seed)
    paths = rng.integers(len(path_set.candidates), size=n)
    ego = np.zeros((n, 8))
    others = np.zeros((n, 16, 6))
    for b, p in enumerate(paths):
        c = path_set.candidates[p]
        i = rng.integers(len(c.points) - 1)
        ego[b, :2] = c.points[i] + rng.normal(0.0, 0.5, 2)
        ego[b, 2] = rng.uniform(0.0, 9.0)
        ego[b, 3] = rng.normal(0.0, 0.1)
        ego[b, 4] = c.heading[i] + rng.normal(0.0, 0.1)
        ego[b, 5] = rng.normal(0.0, 0.1)
        ego[b, 6] = rng.uniform(-0.2, 0.2)
        ego[b, 7] = rng.uniform(-2.0, 1.0)
        dist = rng.uniform(3.0, 25.0, 16)
        ang = rng.uniform(-np.pi, np.pi, 16)
        others[b, :, 0] = ego[b, 0] + dist * np.cos(ang)
        others[b, :, 1] = ego[b, 1] + dist * np.sin(ang)
        others[b, :, 2] = rng.uniform(0.0, 8.0, 16)
        others[b, :, 3] = rng.uniform(-np.pi, np.pi, 16)
        others[b, :, 4] = rng.uniform(0.5, EGO_LENGTH_M, 16)
        others[b, :, 5] = rng.uniform(0.5, EGO_WIDTH_M, 16)
    kappa = rng.uniform(-0.05, 0.05, (n, 16))
    stop = rng.random(n) < 0.5
    t = lambda a: torch.as_tensor(a, dtype=dtype)  # noqa: E731
    return StateBatch(t(ego), t(others), t(kappa), torch.as_tensor(paths, dtype=torch.long),
                      torch.as_tensor(stop))
