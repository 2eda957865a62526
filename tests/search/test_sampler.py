"""The search's TPE keeps every failure on its good side (engine.FailureSplit): it proposes where
failures have been found most, not only around the first few; with a pool of seeds it comes back
to the traffic that failed."""

from __future__ import annotations

import optuna
from optuna.distributions import CategoricalDistribution, FloatDistribution
from optuna.trial import create_trial

from crossroads.search.engine import FailureSplit, make_sampler
from crossroads.search.objective import FAILURE_VALUE

X = {"x": FloatDistribution(0.0, 1.0)}


def test_the_split_holds_every_failure_and_at_least_optunas_default_share() -> None:
    assert FailureSplit(0)(10) == 1 and FailureSplit(0)(100) == 10 and FailureSplit(0)(1000) == 25
    assert FailureSplit(3)(10) == 3 and FailureSplit(60)(200) == 60
    assert FailureSplit(2)(100) == 10  # fewer failures than the default share: the best margins join them


def proposals(failing_told: int | None) -> list[float]:
    """Where TPE proposes after 3 early failures near x = 0.1, 30 comfortable episodes, and then 12
    failures near x = 0.8: with ``failing_told`` failures on its good side (None: optuna's split)."""
    study = optuna.create_study(direction="minimize")
    trials = [(0.08 + 0.02 * i, FAILURE_VALUE) for i in range(3)]
    trials += [(i / 30.0, 0.5 + i / 60.0) for i in range(30)]
    trials += [(0.75 + 0.01 * i, FAILURE_VALUE) for i in range(12)]
    for x, value in trials:
        study.add_trial(create_trial(params={"x": x}, distributions=X, value=value))
    out = []
    for seed in range(20):
        if failing_told is None:
            study.sampler = optuna.samplers.TPESampler(seed=seed, multivariate=True, n_startup_trials=10)
        else:
            study.sampler = make_sampler("tpe", seed, failing_told)
        trial = study.ask(X)
        out.append(trial.params["x"])
        study.tell(trial, state=optuna.trial.TrialState.FAIL)  # not told: the next proposal sees the same
    return out


def test_tpe_follows_the_region_where_most_failures_were_found() -> None:
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    ours = proposals(15)
    default = proposals(None)
    near_late = sum(0.7 <= x <= 0.9 for x in ours)
    # optuna's split (5 trials: the 3 early failures and 2 late ones) counts 10 late failures as bad
    assert sum(0.7 <= x <= 0.9 for x in default) < sum(0.0 <= x <= 0.2 for x in default)
    assert near_late > sum(0.0 <= x <= 0.2 for x in ours) and near_late >= 10


def test_with_a_pool_of_seeds_tpe_comes_back_to_the_traffic_that_failed() -> None:
    """Eight seeds, 40 episodes told: the failures all came with seed 13 (and x above 0.5), every
    other seed passed. TPE proposes seed 13 far more often than the one in eight of a uniform draw,
    and random sampling of the same space does not."""
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    space = {"seed": CategoricalDistribution([3, 5, 8, 13, 21, 34, 55, 89]), **X}
    study = optuna.create_study(direction="minimize")
    for i in range(40):
        seed, x = space["seed"].choices[i % 8], (i * 0.37) % 1.0
        value = FAILURE_VALUE if seed == 13 and x > 0.5 else 0.6 + 0.01 * i
        study.add_trial(create_trial(params={"seed": seed, "x": x}, distributions=space, value=value))
    failing = sum(t.value == FAILURE_VALUE for t in study.trials)
    assert failing >= 2

    def seeds(kind: str) -> list[int]:
        out = []
        for sampler_seed in range(40):
            study.sampler = make_sampler(kind, sampler_seed, failing)
            trial = study.ask(space)
            out.append(trial.params["seed"])
            study.tell(trial, state=optuna.trial.TrialState.FAIL)
        return out

    assert seeds("tpe").count(13) >= 20
    assert seeds("random").count(13) <= 12
