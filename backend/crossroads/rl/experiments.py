"""Named training experiments: recipes that depart from the paper's configuration, by name.

``TrainConfig()`` is the paper's configuration (:mod:`crossroads.rl.config`). An experiment here
is a named set of its fields' values, what it is for, and where its measured effect is written.
``crossroads train --experiment NAME`` (repeatable) applies them in order, before any ``--set``, so
``--set`` still has the last word; the run's config records their names (``TrainConfig.experiments``),
and so does its model card.

Each experiment sets every value it depends on, so that one applied after another still gives its
own recipe. An experiment that lost is removed from here and its options from the code
(``rl.config.REMOVED_OPTIONS``); its result stays on docs/tried/training.md.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from crossroads.rl.config import TRIED_PAGE, TrainConfig, apply_overrides


@dataclass(frozen=True)
class Experiment:
    """One named recipe on top of the paper's configuration."""

    name: str
    description: str
    """One line: what it changes and what for."""
    overrides: Mapping[str, Any]
    """TrainConfig field → value (typed as the field is)."""
    measured: str
    """Where its measured effect is written: a docs page, with its section's anchor."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "overrides", MappingProxyType(dict(self.overrides)))  # read-only


SHORT_RUN_LR = (1e-3, 1e-5)
"""Policy, value and adversary learning rate (start → end) of runs far shorter than the paper's."""

FINE_TUNE_LR = (1e-4, 1e-5)
"""Policy and value learning rate of the warm-started runs behind the kept APG models."""

SLOW_ADVERSARY_LR = (3e-5, 1e-6)
"""The adversary's learning rate of those runs: ten times slower than the policy's (APG 18 → 33 passes)."""

_FINE_TUNE: dict[str, Any] = {
    "policy_lr": FINE_TUNE_LR, "value_lr": FINE_TUNE_LR, "adversary_lr": SLOW_ADVERSARY_LR,
    "max_grad_norm": 10.0, "rule_share": 0.25, "samples_per_iteration": 64.0,
    "braking_floor": True, "empty_share": 0.2, "path_preview": True,
}  # what the last runs behind models/apg.pt and models/pooled/apg.pt share (their cards' configs)

_ALL = (
    Experiment(
        "short-run",
        "runs far shorter than the paper's 200 000 iterations: learning rates 1e-3 → 1e-5 for all three "
        "networks, gradients clipped to norm 10, half the sampling rounds driven by the rule controller",
        {"policy_lr": SHORT_RUN_LR, "value_lr": SHORT_RUN_LR, "adversary_lr": SHORT_RUN_LR,
         "max_grad_norm": 10.0, "rule_share": 0.5},
        f"{TRIED_PAGE}#learning-rates-for-runs-shorter-than-the-papers",
    ),
    Experiment(
        "shipped-apg",
        "the last run of the shipped APG (models/apg.pt): the pooled model's recipe (participants "
        "through one pooled encoder of 64 units, the stopping tail, the lead summary, the braking floor, "
        "the path preview, lr 1e-4 → 1e-5 with an adversary ten times slower) with the log loss; it ran "
        "500 iterations of a 3 000-iteration schedule, warm-started from models/pooled/apg.pt "
        "(--set init_from=...)",
        {**_FINE_TUNE, "policy_loss": "log", "participant_encoder": 64, "stopping_tail": 40, "lead_input": True},
        f"{TRIED_PAGE}#pooled-participants-with-the-log-loss-2026-12-08",
    ),
    Experiment(
        "pooled",
        "the last run of models/pooled/apg.pt: participants through one pooled encoder of 64 units, the "
        "stopping tail, the lead summary and the paper's mean loss on the shipped APG's recipe; its warm "
        "start needs pooled networks (models/pooled/apg.pt, or crossroads train distill)",
        {**_FINE_TUNE, "policy_loss": "mean", "participant_encoder": 64, "stopping_tail": 40, "lead_input": True},
        f"{TRIED_PAGE}#pooled-participants-2026-12-04",
    ),
)

EXPERIMENTS: Mapping[str, Experiment] = MappingProxyType({e.name: e for e in _ALL})
"""Every named experiment, by name."""


def apply_experiments(config: TrainConfig, names: Sequence[str]) -> TrainConfig:
    """``config`` with the named experiments applied in order and recorded in ``experiments``;
    an unknown name raises ValueError listing the known ones."""
    for name in names:
        experiment = EXPERIMENTS.get(name)
        if experiment is None:
            raise ValueError(f"unknown experiment {name!r}; known: {', '.join(EXPERIMENTS)}")
        config = apply_overrides(config, {**experiment.overrides, "experiments": (*config.experiments, name)})
    return config


__all__ = ["EXPERIMENTS", "Experiment", "apply_experiments"]
