"""Batch metrics: Wilson interval, pass rate without errored episodes, travel time, McNemar."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from crossroads.evaluation import metrics
from crossroads.evaluation.episode import EpisodeResult
from crossroads.evaluation.metrics import (
    Z_95,
    BatchSummary,
    binomial_cdf_half,
    compare_paired,
    mcnemar_exact,
    mcnemar_p_value,
    normal_quantile,
    outcome_counts,
    pass_rate,
    summarize,
    travel_time_stats,
    wilson_interval,
)

counts = st.integers(min_value=0, max_value=2000).flatmap(
    lambda n: st.tuples(st.integers(min_value=0, max_value=n), st.just(n)))


def ep(seed: int, outcome: str, travel: float | None = None, **kw) -> dict:
    return {"seed": seed, "outcome": outcome, "travel_time_s": travel, **kw}


# --- Wilson -----------------------------------------------------------------------------------------


@pytest.mark.parametrize(("k", "n", "low", "high"), [
    # Newcombe (1998), Stat. Med. 17:857, Table I, method 3 (score interval without correction)
    (81, 263, 0.2553, 0.3662), (15, 148, 0.0624, 0.1605), (0, 20, 0.0, 0.1611), (1, 29, 0.0061, 0.1718),
    (8, 10, 0.4902, 0.9433),
])
def test_wilson_known_values(k: int, n: int, low: float, high: float) -> None:
    assert wilson_interval(k, n) == pytest.approx((low, high), abs=5e-5)


def test_wilson_edges() -> None:
    assert wilson_interval(0, 0) == (0.0, 1.0)
    low, high = wilson_interval(0, 20)
    assert low == 0.0 and 0 < high < 0.2
    low, high = wilson_interval(200, 200)
    assert high == 1.0 and low == pytest.approx(1 / (1 + Z_95**2 / 200))
    for bad in ((-1, 3), (4, 3), (0, -1)):
        with pytest.raises(ValueError):
            wilson_interval(*bad)
    with pytest.raises(ValueError):
        wilson_interval(1, 2, confidence=1.0)


def test_normal_quantile() -> None:
    assert normal_quantile(0.975) == pytest.approx(Z_95, abs=1e-12)
    assert normal_quantile(0.995) == pytest.approx(2.5758293035489004, abs=1e-12)
    assert normal_quantile(0.5) == pytest.approx(0.0, abs=1e-12)
    assert normal_quantile(0.025) == pytest.approx(-Z_95, abs=1e-12)


@given(counts)
def test_wilson_contains_estimate_within_unit_interval(kn: tuple[int, int]) -> None:
    k, n = kn
    low, high = wilson_interval(k, n)
    assert 0.0 <= low <= high <= 1.0
    if n:
        assert low <= k / n <= high


@given(counts, st.integers(min_value=2, max_value=10))
def test_wilson_narrows_with_n(kn: tuple[int, int], factor: int) -> None:
    k, n = kn
    if n == 0:
        return
    low1, high1 = wilson_interval(k, n)
    low2, high2 = wilson_interval(k * factor, n * factor)  # same estimate, more runs
    assert high2 - low2 < high1 - low1


@given(counts)
def test_wilson_widens_with_confidence(kn: tuple[int, int]) -> None:
    k, n = kn
    if n == 0:
        return
    l90, h90 = wilson_interval(k, n, confidence=0.90)
    l95, h95 = wilson_interval(k, n)
    l99, h99 = wilson_interval(k, n, confidence=0.99)
    assert h90 - l90 < h95 - l95 < h99 - l99


# --- pass rate, travel time, outcomes ---------------------------------------------------------------


def test_pass_rate_excludes_errors() -> None:
    results = [ep(0, "passed", 10.0), ep(1, "collision"), ep(2, "passed", 12.0),
               ep(3, "timeout", error="SUMO died"), ep(4, "error", error="killed")]
    assert pass_rate(results) == pytest.approx(2 / 3)
    assert pass_rate([]) is None
    assert pass_rate([ep(0, "error", error="x")]) is None


def test_travel_time_stats_sample_std_over_passed() -> None:
    times = [10.0, 12.5, 13.0, 17.25]
    results = [ep(i, "passed", t) for i, t in enumerate(times)]
    results += [ep(10, "collision", 99.0), ep(11, "passed", 50.0, error="crashed"), ep(12, "passed", None)]
    stats = travel_time_stats(results)
    assert stats.n == 4
    assert stats.mean == pytest.approx(np.mean(times))
    assert stats.std == pytest.approx(np.std(times, ddof=1))
    assert travel_time_stats([ep(0, "passed", 3.0)]) == (3.0, None, 1)
    assert travel_time_stats([]) == (None, None, 0)


def test_outcome_counts_all_keys_and_errors_separate() -> None:
    results = [ep(0, "passed"), ep(1, "passed"), ep(2, "red_light"), ep(3, "passed", error="boom"),
               ep(4, "weird")]
    c = outcome_counts(results)
    assert list(c)[:6] == ["passed", "collision", "red_light", "off_road", "timeout", "error"]
    assert c == {"passed": 2, "collision": 0, "red_light": 1, "off_road": 0, "timeout": 0, "error": 1,
                 "weird": 1}


def test_summarize_episode_results_and_dicts_agree() -> None:
    objs = [EpisodeResult(seed=i, outcome="passed" if i % 4 else "collision", steps=10, time_s=20.0,
                          travel_time_s=10.0 + i if i % 4 else None, min_distance_m=2.0)
            for i in range(20)]
    s = summarize(objs)
    assert s == summarize([o.to_json() for o in objs])
    assert (s.runs, s.errors, s.passed, s.valid) == (20, 0, 15, 20)
    assert s.pass_rate == 0.75
    assert (s.wilson_low, s.wilson_high) == wilson_interval(15, 20)
    assert s.travel_n == 15 and s.travel_mean_s == pytest.approx(np.mean([10 + i for i in range(20) if i % 4]))
    assert s.outcomes["collision"] == 5
    assert BatchSummary.from_json(s.to_json()) == s
    assert s.to_json()["valid"] == 20


def test_summarize_errors_and_empty() -> None:
    s = summarize([ep(0, "passed", 9.0), ep(1, "error", error="worker killed")])
    assert (s.runs, s.errors, s.passed, s.pass_rate) == (2, 1, 1, 1.0)
    empty = summarize([])
    assert empty.pass_rate is None and (empty.wilson_low, empty.wilson_high) == (0.0, 1.0)
    assert empty.travel_mean_s is None and empty.travel_std_s is None


# --- McNemar ----------------------------------------------------------------------------------------


def paired(a: list[bool], b: list[bool]) -> tuple[list[dict], list[dict]]:
    return ([ep(i, "passed" if x else "collision") for i, x in enumerate(a)],
            [ep(i, "passed" if x else "timeout") for i, x in enumerate(b)])


@pytest.mark.parametrize(("b01", "b10", "p"), [
    (0, 6, 0.03125), (6, 0, 0.03125), (1, 9, 0.021484375), (9, 1, 0.021484375),
    (0, 0, 1.0), (3, 3, 1.0), (2, 3, 1.0), (0, 1, 1.0), (0, 5, 0.0625),
])
def test_mcnemar_known_values(b01: int, b10: int, p: float) -> None:
    assert mcnemar_p_value(b01, b10) == p
    a, b = paired([False] * b01 + [True] * b10 + [True] * 4, [True] * b01 + [False] * b10 + [True] * 4)
    assert mcnemar_exact(a, b) == (b01, b10, p)


def exact_p(b01: int, b10: int) -> float:
    n = b01 + b10
    if n == 0:
        return 1.0
    tail = Fraction(sum(math.comb(n, i) for i in range(min(b01, b10) + 1)), 2**n)
    return float(min(Fraction(1), 2 * tail))


@given(st.lists(st.tuples(st.booleans(), st.booleans()), max_size=120))
def test_mcnemar_symmetric_and_exact(pairs: list[tuple[bool, bool]]) -> None:
    a, b = paired([x for x, _ in pairs], [y for _, y in pairs])
    b01, b10, p = mcnemar_exact(a, b)
    assert (b10, b01, p) == mcnemar_exact(b, a)
    assert b01 == sum(1 for x, y in pairs if not x and y)
    assert b10 == sum(1 for x, y in pairs if x and not y)
    assert 0.0 < p <= 1.0
    assert p == pytest.approx(exact_p(b01, b10), rel=1e-12)
    if b01 + b10 == 0:
        assert p == 1.0


def test_mcnemar_pairs_common_seeds_without_errors() -> None:
    a = [ep(0, "passed"), ep(1, "passed"), ep(2, "passed"), ep(3, "collision"), ep(7, "passed")]
    b = [ep(0, "collision"), ep(1, "passed", error="SUMO"), ep(2, "timeout"), ep(3, "passed"),
         ep(8, "collision")]
    c = compare_paired(a, b)
    assert (c.pairs, c.both_passed, c.both_failed, c.b01, c.b10) == (3, 0, 0, 1, 2)
    assert c.a_pass_rate == pytest.approx(2 / 3) and c.b_pass_rate == pytest.approx(1 / 3)
    assert c.discordant == 3 and c.p_value == 1.0
    empty = compare_paired([], b)
    assert empty.pairs == 0 and empty.p_value == 1.0 and empty.a_pass_rate is None
    with pytest.raises(ValueError, match="seed 0 occurs twice"):
        compare_paired(a + [ep(0, "passed")], b)


def test_binomial_tail_large_n_log_space(monkeypatch: pytest.MonkeyPatch) -> None:
    exact = [binomial_cdf_half(k, 301) for k in (0, 100, 140, 150)]
    monkeypatch.setattr(metrics, "EXACT_BINOMIAL_MAX_N", 10)
    logspace = [binomial_cdf_half(k, 301) for k in (0, 100, 140, 150)]
    assert logspace == pytest.approx(exact, rel=1e-9)
    assert exact[-1] == pytest.approx(0.5)  # symmetric: P(X <= 150) for n = 301
    assert binomial_cdf_half(-1, 5) == 0.0 and binomial_cdf_half(5, 5) == 1.0


def test_mcnemar_large_counts_fast_and_sane() -> None:
    p = mcnemar_p_value(50_000, 50_500)  # log-space branch
    assert 0.1 < p < 1.0
    assert mcnemar_p_value(10_000, 10_000) == 1.0
    assert mcnemar_p_value(9_000, 11_000) < 1e-40


def test_blocked_by_the_world_is_counted_apart_and_still_judged() -> None:
    from crossroads.evaluation.metrics import is_blocked

    blocked_event = {"t": 206.0, "event": "blocked_by",
                     "value": {"participant": "veh3", "kind": "vehicle", "stood_s": 204.0, "ahead_m": 9.0}}
    results = [
        {"seed": 1, "outcome": "passed", "travel_time_s": 10.0},
        {"seed": 2, "outcome": "timeout", "events": [blocked_event]},  # as the store keeps it
        {"seed": 3, "outcome": "timeout", "blocked_by": {"participant": "bike1"}},  # EpisodeResult
        {"seed": 4, "outcome": "timeout", "events": [{"t": 1.0, "event": "speed_mode", "value": "stop"}]},
        {"seed": 5, "outcome": "error", "error": "boom", "blocked_by": {"participant": "x"}},
    ]
    assert [is_blocked(r) for r in results] == [False, True, True, False, False]
    s = summarize(results)
    assert s.blocked == 2
    assert s.valid == 4 and s.pass_rate == 0.25  # the paper's definition: passed / judged
