"""The report's main table as Markdown (for READMEs and issue notes): one row per scenario, per
policy its pass rate with the Wilson interval and its travel time, the paper's numbers beside them
where the paper has the case (SPEC §8). Same layout as the HTML report's main table, and like the
HTML report, the batches' stored warnings come first when there are any."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from crossroads.evaluation.metrics import BatchSummary
from crossroads.evaluation.paper import PAPER_TABLE
from crossroads.evaluation.report import (
    BatchRow,
    PaperTable,
    _case_sort_key,
    _columns,
    _num,
    _pct,
    _row_title,
)


def _rate(s: BatchSummary) -> str:
    if s.pass_rate is None:
        return "— (no valid runs)"
    errors = (f", {s.errors} err" if s.errors else "") + (
        f", blocked by the world: {s.blocked}" if s.blocked else "")
    return (f"{_pct(s.pass_rate, 1)} ({s.passed}/{s.valid}{errors}) "
            f"[{_pct(s.wilson_low, 1)}, {_pct(s.wilson_high, 1)}]")


def _travel(s: BatchSummary) -> str:
    return "—" if s.travel_mean_s is None else f"{_num(s.travel_mean_s)} ± {_num(s.travel_std_s)}"


def _warnings(rows: list[BatchRow]) -> list[str]:
    """A list item per stored warning (batch, scenario, policy, text), under a heading; none if none."""
    items = [f"- batch {row.batch_id} ({row.scenario}, {row.policy}): {' '.join(w.split())}"
             for row in rows for w in row.warnings]  # one line each, whatever the text's breaks
    if not items:
        return []
    return ["**Warnings** (recorded when each batch was created, from its network as it was then):",
            "", *items, ""]


def render_markdown(rows: Iterable[BatchRow | Mapping[str, Any]], paper: PaperTable = PAPER_TABLE) -> str:
    """A GitHub-flavoured Markdown table of the batches (see the module docstring)."""
    rows = sorted((BatchRow.coerce(r) for r in rows), key=_case_sort_key)
    if not rows:
        return "_no batches_\n"
    labels, columns = _columns(rows)
    by_cell = {(row.scenario, lab): row for lab, row in zip(labels, rows)}
    with_paper = {lab for lab, row in zip(labels, rows) if row.paper(paper) is not None}
    head = ["case"]
    for col in columns:
        head += [f"{col} pass rate [95 % CI]"] + (["paper"] if col in with_paper else [])
        head += [f"{col} travel time [s]"] + (["paper"] if col in with_paper else [])
    lines = [*_warnings(rows), "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    first = {r.scenario: r for r in rows}
    for scenario in dict.fromkeys(r.scenario for r in rows):
        cells = [_row_title(first[scenario])]
        for col in columns:
            row = by_cell.get((scenario, col))
            n = 4 if col in with_paper else 2
            if row is None:
                cells += ["—"] * n
                continue
            cell = row.paper(paper)
            cells.append(_rate(row.summary))
            if col in with_paper:
                cells.append("—" if cell is None else _pct(cell.pass_rate, 0))
            cells.append(_travel(row.summary))
            if col in with_paper:
                cells.append("—" if cell is None else f"{_num(cell.travel_mean_s)} ± {_num(cell.travel_std_s)}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
