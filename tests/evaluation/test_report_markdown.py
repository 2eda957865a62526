"""The report's main table as Markdown: one line per case, ours beside the paper's numbers."""

from __future__ import annotations

from crossroads.evaluation.metrics import summarize
from crossroads.evaluation.paper import PAPER_CASE_TITLES, PAPER_CASES, PAPER_TABLE
from crossroads.evaluation.report import BatchRow
from crossroads.evaluation.report_markdown import render_markdown

from evaluation.test_report import synthetic_suite


def test_paper_suite_as_markdown() -> None:
    rows = synthetic_suite(runs=60)
    text = render_markdown(rows)
    lines = text.strip().splitlines()
    assert len(lines) == 2 + len(PAPER_CASES)  # header, rule, one line per case
    assert lines[0].count("|") == lines[2].count("|") == 1 + 1 + 2 * 4  # case + 2 policies × 4 cells
    for case, line in zip(PAPER_CASES, lines[2:]):
        assert line.startswith(f"| {PAPER_CASE_TITLES[case]} |")
        for col in ("APG", "DPG"):
            cell = PAPER_TABLE[case][col]
            assert f"{round(cell.pass_rate * 100)} %" in line
            assert f"{cell.travel_mean_s:.2f} ± {cell.travel_std_s:.2f}" in line
    row = rows[0]
    s = row.summary
    assert (f"{100 * s.pass_rate:.1f} % ({s.passed}/{s.valid}" in text
            and f"[{100 * s.wilson_low:.1f} %, {100 * s.wilson_high:.1f} %]" in text)


def test_rows_without_paper_numbers_and_without_valid_runs() -> None:
    text = render_markdown([BatchRow("c_three_lane-left", "rule", "1", summarize([]))])
    assert "| c_three_lane-left | — (no valid runs) | — |" in text
    assert "paper" not in text
    assert render_markdown([]) == "_no batches_\n"


def test_warnings_are_listed_before_the_table() -> None:
    warned = BatchRow("cross-left", "rule", "7", summarize([]),
                      warnings=["internal lanes\nrun up to 3.15 m off", "second"])
    text = render_markdown([warned, BatchRow("cross-left", "apg", "8", summarize([]))])
    lines = text.splitlines()
    table = lines.index(next(line for line in lines if line.startswith("| case |")))
    assert lines[0].startswith("**Warnings**")
    items = [line for line in lines[:table] if line.startswith("- ")]
    assert items == ["- batch 7 (cross-left, rule): internal lanes run up to 3.15 m off",  # one line each
                     "- batch 7 (cross-left, rule): second"]
    assert len(lines) - table == 3  # header, rule, one scenario
