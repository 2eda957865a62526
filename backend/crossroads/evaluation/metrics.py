"""Batch metrics: pass rate with a Wilson interval, travel time, outcome breakdown, paired McNemar test.

Pure functions over episode results. A result is any object or mapping with the fields of
:class:`crossroads.evaluation.episode.EpisodeResult` that a metric needs: ``outcome``
(passed | collision | red_light | off_road | timeout), ``travel_time_s`` (seconds, passed episodes
only), ``seed`` (for pairing) and, for an episode that crashed instead of coming to an outcome
(SUMO error, exception, killed worker), a truthy ``error`` (its message) or ``outcome == "error"``.

Errored episodes say nothing about the policy, so they are **excluded** from the pass rate and its
interval and counted separately (``BatchSummary.errors``, ``outcome_counts()["error"]``)::

    valid     = runs − errors
    pass rate = passed / valid

This differs from the paper's "passes / 200 runs" only when episodes errored; a report shows the
error count next to the rate so that a batch with many errors stands out.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any, NamedTuple

OUTCOMES: tuple[str, ...] = ("passed", "collision", "red_light", "off_road", "timeout")
"""The outcomes a world judges, in report order."""
ERROR = "error"
"""The pseudo-outcome of an episode that crashed."""

Z_95 = 1.959963984540054
"""Φ⁻¹(0.975): the two-sided 95 % standard normal quantile."""

EXACT_BINOMIAL_MAX_N = 20_000
"""Above this many discordant pairs the McNemar tail is summed in log space instead of exactly."""


# --------------------------------------------------------------------------------------------------
# access to results given as objects or mappings


def _field(result: Any, name: str, default: Any = None) -> Any:
    if isinstance(result, Mapping):
        return result.get(name, default)
    return getattr(result, name, default)


def is_error(result: Any) -> bool:
    """Whether ``result`` is a crashed episode (truthy ``error`` or ``outcome == "error"``)."""
    return bool(_field(result, "error")) or _field(result, "outcome") == ERROR


def is_blocked(result: Any) -> bool:
    """Whether ``result`` timed out behind a participant that barred every candidate path the
    whole episode: the world's failure, not the driver's (``blocked_by``, or its episode event)."""
    if is_error(result):
        return False
    if _field(result, "blocked_by"):
        return True
    events = _field(result, "events") or ()
    return any(isinstance(e, Mapping) and e.get("event") == "blocked_by" for e in events)


def is_passed(result: Any) -> bool:
    """Whether ``result`` passed (and did not error)."""
    return not is_error(result) and _field(result, "outcome") == "passed"


# --------------------------------------------------------------------------------------------------
# proportions


def normal_quantile(p: float) -> float:
    """Φ⁻¹(p) of the standard normal, by bisection on ``erfc`` (to machine precision)."""
    if not 0.0 < p < 1.0:
        raise ValueError(f"normal_quantile needs 0 < p < 1, got {p}")
    lo, hi = -40.0, 40.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if 0.5 * math.erfc(-mid / math.sqrt(2.0)) < p:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * max(1.0, abs(mid)):
            break
    return 0.5 * (lo + hi)


def _z(confidence: float) -> float:
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    if confidence == 0.95:
        return Z_95
    return normal_quantile(0.5 + confidence / 2.0)


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion.

    With p̂ = successes / n and z = Φ⁻¹((1 + confidence) / 2) (exactly 1.959963984540054 for 95 %)::

        centre = (p̂ + z² / 2n) / (1 + z² / n)
        half   = z / (1 + z² / n) · √(p̂ (1 − p̂) / n + z² / 4n²)
        (low, high) = (centre − half, centre + half)

    The ends are exactly 0 when successes = 0 and exactly 1 when successes = n (rounding could
    otherwise leave p̂ a hair outside). ``n = 0`` gives the uninformative (0, 1).
    """
    if n < 0 or successes < 0 or successes > n:
        raise ValueError(f"need 0 <= successes <= n, got successes={successes}, n={n}")
    z = _z(confidence)
    if n == 0:
        return (0.0, 1.0)
    p = successes / n
    z2 = z * z
    denom = 1.0 + z2 / n
    centre = (p + z2 / (2.0 * n)) / denom
    half = z / denom * math.sqrt(p * (1.0 - p) / n + z2 / (4.0 * n * n))
    low = 0.0 if successes == 0 else min(p, max(0.0, centre - half))
    high = 1.0 if successes == n else max(p, min(1.0, centre + half))
    return (low, high)


def pass_rate(results: Iterable[Any]) -> float | None:
    """passed / (runs − errors); ``None`` when no episode came to an outcome.

    Errored episodes are left out of numerator and denominator (see the module docstring).
    """
    passed = valid = 0
    for r in results:
        if is_error(r):
            continue
        valid += 1
        passed += _field(r, "outcome") == "passed"
    return passed / valid if valid else None


# --------------------------------------------------------------------------------------------------
# travel time


class TravelTimeStats(NamedTuple):
    """Travel time over the passed episodes: mean, sample std (ddof = 1) and their count."""

    mean: float | None  # [s]; None when n = 0
    std: float | None  # [s]; None when n < 2
    n: int


def travel_times(results: Iterable[Any]) -> list[float]:
    """The travel times [s] of the passed episodes that carry one, in input order."""
    out: list[float] = []
    for r in results:
        t = _field(r, "travel_time_s")
        if is_passed(r) and t is not None and math.isfinite(float(t)):
            out.append(float(t))
    return out


def mean_std(values: Iterable[float]) -> TravelTimeStats:
    """mean = Σx / n;  std = √(Σ(x − mean)² / (n − 1)) (two-pass, ``math.fsum``)."""
    xs = [float(v) for v in values]
    n = len(xs)
    if n == 0:
        return TravelTimeStats(None, None, 0)
    mean = math.fsum(xs) / n
    if n < 2:
        return TravelTimeStats(mean, None, 1)
    var = math.fsum((x - mean) ** 2 for x in xs) / (n - 1)
    return TravelTimeStats(mean, math.sqrt(var), n)


def travel_time_stats(results: Iterable[Any]) -> TravelTimeStats:
    """Mean and sample std (ddof = 1) of ``travel_time_s`` over the passed episodes."""
    return mean_std(travel_times(results))


# --------------------------------------------------------------------------------------------------
# outcomes and the batch summary


def outcome_counts(results: Iterable[Any]) -> dict[str, int]:
    """Episodes per outcome: every key of :data:`OUTCOMES` (zeros included), then ``error``, then
    any other outcome a result names, in order of first appearance. An errored episode counts
    only under ``error``, whatever its ``outcome`` field says."""
    counts: dict[str, int] = {k: 0 for k in (*OUTCOMES, ERROR)}
    for r in results:
        key = ERROR if is_error(r) else str(_field(r, "outcome"))
        counts[key] = counts.get(key, 0) + 1
    return counts


@dataclass(frozen=True)
class BatchSummary:
    """The metrics of one batch. ``valid = runs − errors`` is the pass rate's denominator."""

    runs: int
    errors: int
    passed: int
    pass_rate: float | None  # passed / valid; None when valid = 0
    wilson_low: float  # Wilson interval of pass_rate at ``confidence``
    wilson_high: float
    travel_mean_s: float | None
    travel_std_s: float | None  # sample std, ddof = 1
    travel_n: int
    outcomes: dict[str, int] = field(default_factory=dict)
    confidence: float = 0.95
    # timeouts blocked by the world (:func:`is_blocked`); still judged: the pass rate keeps the
    # paper's definition, passed / judged
    blocked: int = 0

    @property
    def valid(self) -> int:
        return self.runs - self.errors

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict (``valid`` included)."""
        out = asdict(self)
        out["valid"] = self.valid
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> BatchSummary:
        """Inverse of :meth:`to_json` (unknown keys such as ``valid`` are ignored)."""
        names = {f for f in cls.__dataclass_fields__}
        kwargs = {k: v for k, v in data.items() if k in names}
        kwargs["outcomes"] = dict(kwargs.get("outcomes") or {})
        return cls(**kwargs)


def summarize(results: Iterable[Any], confidence: float = 0.95) -> BatchSummary:
    """:class:`BatchSummary` of any iterable of results (objects or mappings)."""
    items = list(results)
    counts = outcome_counts(items)
    errors = counts[ERROR]
    passed = counts["passed"]
    valid = len(items) - errors
    low, high = wilson_interval(passed, valid, confidence)
    tt = travel_time_stats(items)
    return BatchSummary(
        runs=len(items), errors=errors, passed=passed,
        pass_rate=passed / valid if valid else None,
        wilson_low=low, wilson_high=high,
        travel_mean_s=tt.mean, travel_std_s=tt.std, travel_n=tt.n,
        outcomes=counts, confidence=confidence, blocked=sum(1 for r in items if is_blocked(r)),
    )


# --------------------------------------------------------------------------------------------------
# paired comparison


def binomial_cdf_half(k: int, n: int) -> float:
    """P(X ≤ k) for X ~ Bin(n, ½), i.e. Σ_{i≤k} C(n, i) / 2ⁿ.

    Exact integer arithmetic (a correctly rounded final division) up to
    :data:`EXACT_BINOMIAL_MAX_N`; above, a log-sum-exp of ``lgamma`` terms.
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    if k < 0:
        return 0.0
    if k >= n:
        return 1.0
    if n <= EXACT_BINOMIAL_MAX_N:
        term = total = 1  # C(n, 0)
        for i in range(k):
            term = term * (n - i) // (i + 1)  # C(n, i + 1), exact
            total += term
        return total / (1 << n)
    log_terms = [math.lgamma(n + 1) - math.lgamma(i + 1) - math.lgamma(n - i + 1) for i in range(k + 1)]
    top = max(log_terms)
    log_sum = top + math.log(math.fsum(math.exp(t - top) for t in log_terms))
    return min(1.0, math.exp(log_sum - n * math.log(2.0)))


def _outcome_by_seed(results: Iterable[Any], which: str) -> dict[int, Any]:
    by_seed: dict[int, Any] = {}
    for r in results:
        seed = _field(r, "seed")
        if seed is None:
            raise ValueError(f"{which}: a result has no seed; paired comparison needs seeds")
        seed = int(seed)
        if seed in by_seed:
            raise ValueError(f"{which}: seed {seed} occurs twice; pair batches with one episode per seed")
        by_seed[seed] = r
    return by_seed


@dataclass(frozen=True)
class PairedComparison:
    """Policies A and B on the same seeds. ``b01``: A failed, B passed; ``b10``: A passed, B failed.

    ``p_value`` is the two-sided exact McNemar test of "A and B pass equally often" (see
    :func:`mcnemar_exact`); it is 1 when there are no discordant pairs.
    """

    pairs: int
    both_passed: int
    both_failed: int
    b01: int
    b10: int
    p_value: float
    a_pass_rate: float | None  # over the pairs
    b_pass_rate: float | None

    @property
    def discordant(self) -> int:
        return self.b01 + self.b10

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def compare_paired(a_results: Iterable[Any], b_results: Iterable[Any]) -> PairedComparison:
    """Pair two batches by seed and test them with :func:`mcnemar_exact`.

    Only the seeds both batches ran are paired, and a seed where either episode errored is
    dropped. A seed that occurs twice in one batch is a :class:`ValueError`.
    """
    a = _outcome_by_seed(a_results, "a_results")
    b = _outcome_by_seed(b_results, "b_results")
    n11 = n00 = b01 = b10 = 0
    for seed in a.keys() & b.keys():
        ra, rb = a[seed], b[seed]
        if is_error(ra) or is_error(rb):
            continue
        pa, pb = is_passed(ra), is_passed(rb)
        if pa and pb:
            n11 += 1
        elif pa:
            b10 += 1
        elif pb:
            b01 += 1
        else:
            n00 += 1
    pairs = n11 + n00 + b01 + b10
    return PairedComparison(
        pairs=pairs, both_passed=n11, both_failed=n00, b01=b01, b10=b10,
        p_value=mcnemar_p_value(b01, b10),
        a_pass_rate=(n11 + b10) / pairs if pairs else None,
        b_pass_rate=(n11 + b01) / pairs if pairs else None,
    )


def mcnemar_p_value(b01: int, b10: int) -> float:
    """Two-sided exact McNemar p: min(1, 2 · P(X ≤ min(b01, b10))) with X ~ Bin(b01 + b10, ½)."""
    if b01 < 0 or b10 < 0:
        raise ValueError(f"discordant counts must be >= 0, got {b01}, {b10}")
    n = b01 + b10
    if n == 0:
        return 1.0
    return min(1.0, 2.0 * binomial_cdf_half(min(b01, b10), n))


def mcnemar_exact(a_results: Iterable[Any], b_results: Iterable[Any]) -> tuple[int, int, float]:
    """Exact McNemar test of two batches paired by seed: ``(b01, b10, p_value)``.

    ``b01`` counts the seeds A failed and B passed, ``b10`` the reverse; pairing as in
    :func:`compare_paired` (common seeds, neither errored). p as in :func:`mcnemar_p_value`.
    """
    c = compare_paired(a_results, b_results)
    return c.b01, c.b10, c.p_value
