"""The paper's generalization results (Sec. V-C; SPEC §8) as data, for reports to set beside ours.

Unprotected left turn on green, 200 runs per case. Case 1 (overspeed): 15 % of the vehicles in the
opposite straight lane exceed the limit by 10/20/50 %. Case 2 (rounding): 10/20/50 % of the vehicles
violate the lane connection and turn into the inside lane. APG and DPG are the paper's two policy
gradient variants.

The numbers are copied from SPEC §8 as printed: passing rate (a fraction here, e.g. 0.90 for 90 %)
and travel time mean ± std in seconds (stop line to leaving the intersection, passed runs only).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

PAPER_RUNS = 200
"""Runs per case in the paper (the denominator of its passing rate)."""

PAPER_POLICIES: tuple[str, ...] = ("APG", "DPG")

PAPER_CASES: tuple[str, ...] = (
    "overspeed-10", "overspeed-20", "overspeed-50",
    "rounding-10", "rounding-20", "rounding-50",
)
"""Case labels in the paper's row order; they are also the names of scenarios/paper/*.yaml."""

PAPER_CASE_TITLES: Mapping[str, str] = MappingProxyType({
    "overspeed-10": "overspeed +10 %",
    "overspeed-20": "overspeed +20 %",
    "overspeed-50": "overspeed +50 %",
    "rounding-10": "rounding 10 %",
    "rounding-20": "rounding 20 %",
    "rounding-50": "rounding 50 %",
})
"""The row headings as the paper prints them."""


@dataclass(frozen=True)
class PaperResult:
    """One cell of the paper's table: one policy on one case."""

    pass_rate: float  # fraction of the 200 runs that passed
    travel_mean_s: float  # [s]
    travel_std_s: float  # [s]

    @property
    def passes(self) -> int:
        """Passed runs out of :data:`PAPER_RUNS` implied by the printed rate."""
        return round(self.pass_rate * PAPER_RUNS)


PAPER_TABLE: Mapping[str, Mapping[str, PaperResult]] = MappingProxyType({
    "overspeed-10": MappingProxyType({"APG": PaperResult(1.00, 13.08, 2.35),
                                      "DPG": PaperResult(0.90, 12.30, 3.96)}),
    "overspeed-20": MappingProxyType({"APG": PaperResult(0.90, 13.38, 4.98),
                                      "DPG": PaperResult(0.82, 12.08, 1.71)}),
    "overspeed-50": MappingProxyType({"APG": PaperResult(0.90, 16.18, 4.85),
                                      "DPG": PaperResult(0.75, 10.33, 3.28)}),
    "rounding-10": MappingProxyType({"APG": PaperResult(0.96, 12.83, 3.07),
                                     "DPG": PaperResult(0.80, 12.71, 2.88)}),
    "rounding-20": MappingProxyType({"APG": PaperResult(0.94, 13.38, 3.91),
                                     "DPG": PaperResult(0.72, 12.30, 3.96)}),
    "rounding-50": MappingProxyType({"APG": PaperResult(0.84, 13.60, 3.58),
                                     "DPG": PaperResult(0.34, 10.50, 4.94)}),
})
"""case label → paper policy (``APG`` | ``DPG``) → :class:`PaperResult`."""
