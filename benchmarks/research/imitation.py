"""What the imitation probes share (``dagger.py``, ``shield_dagger.py``): fitting a driving
policy's mean to labelled actions."""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

LOSS_WINDOW = 50  # the fit's reported loss: the mean of its last this many steps
Z_LIMIT = 3.0  # (choice) labels before tanh are clipped here: tanh(3) = 0.995 of the range


def fit_mean(policy: torch.nn.Module, states: Tensor, z: Tensor, steps: int, lr: float, batch_size: int,
             generator: torch.Generator, weights: Tensor | None = None, squashed: bool = False) -> float:
    """Adam on the MSE between the policy's mean before tanh on ``states`` and the labels ``z``
    (both before tanh), or with ``squashed`` between their tanh (the actions as shares of their
    ranges: a saturated mean beyond a saturated label costs nothing); batches drawn uniformly, or
    in proportion to ``weights``. The mean loss of the last ``LOSS_WINDOW`` steps."""
    optimiser = torch.optim.Adam(policy.parameters(), lr=lr)
    policy.train()
    size = min(batch_size, len(states))
    losses = []
    for _ in range(steps):
        rows = (torch.randint(len(states), (size,), generator=generator) if weights is None
                else torch.multinomial(weights, size, replacement=True, generator=generator))
        mean, _ = policy.distribution(states[rows])
        loss = (torch.nn.functional.mse_loss(torch.tanh(mean), torch.tanh(z[rows])) if squashed
                else torch.nn.functional.mse_loss(mean, z[rows]))
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        losses.append(float(loss.detach()))
    policy.eval()
    return float(np.mean(losses[-LOSS_WINDOW:]))
