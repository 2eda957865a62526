"""The search's objective: how close an episode came to failing (lower is closer; failures lowest).

A failure (an outcome the space counts as one) scores ``FAILURE_VALUE`` = −1. Any other episode
scores its *margin* in [0, 1]: the smallest of its near-miss figures (``EpisodeResult.min_gap_m``,
``min_ttc_s``, ``red_stop_margin_m``; see :mod:`crossroads.evaluation.near_miss`), each divided by
the scale at which it stops being a near miss and clipped to [0, 1]. A figure that was not
measured counts 1. So a search that minimises the objective climbs from comfortable episodes
through near misses (a 0.3 m gap, a 0.5 s time to collision, a red light it could barely stop for)
to failures. An episode that crashed (outcome ``error``) has no score.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

FAILURE_VALUE = -1.0
GAP_SCALE_M = 2.0  # [m] a footprint gap of this much or more is no near miss
TTC_SCALE_S = 3.0  # [s] a time to collision of this much or more is no near miss
RED_SCALE_M = 5.0  # [m] a stopping margin on red of this much or more is no near miss


def _part(value: Any, scale: float) -> float:
    if value is None:
        return 1.0
    return min(max(float(value) / scale, 0.0), 1.0)


def margin(result: Mapping[str, Any]) -> float:
    """The near-miss margin in [0, 1] of an episode's result (its JSON)."""
    return min(_part(result.get("min_gap_m"), GAP_SCALE_M),
               _part(result.get("min_ttc_s"), TTC_SCALE_S),
               _part(result.get("red_stop_margin_m"), RED_SCALE_M))


def objective(result: Mapping[str, Any] | None, failures: Iterable[str]) -> float | None:
    """The objective of an episode (None for one that crashed: ``result`` None or outcome error)."""
    if result is None or result.get("outcome") == "error":
        return None
    if result["outcome"] in set(failures):
        return FAILURE_VALUE
    return round(margin(result), 6)
