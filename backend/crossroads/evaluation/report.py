"""Evaluation reports: one self-contained HTML file (and a CSV) over any set of batches.

A :class:`BatchRow` describes one batch (scenario, policy, batch id, its :class:`BatchSummary`, the
travel times of its passed episodes, its failed episodes, its outcome per seed for paired
comparisons, and the warnings stored with it); :meth:`BatchRow.from_results` builds one from
episode results. :func:`render_html` lists the batches' warnings first (when there are any), then
lays the rows out like the paper's table (SPEC §8): one line per case (scenario), per policy the
pass rate with its Wilson 95 % interval and the travel time mean ± std, with the paper's own numbers
beside ours where the case and policy match the paper's. Then come plots (pass rate against the
injection level; travel-time distributions) as inline base64 PNGs, exact McNemar tests where two
policies ran the same scenario, the outcome breakdown per batch and the failed episodes with links
to their traces. :func:`write_csv` writes one line per batch with every summary field.

Matching the paper: a scenario's *case* is read from its name (``overspeed-10``,
``paper_rounding_50`` → ``rounding-50``; see :func:`case_label`), a policy's paper column from its
name (``models/apg.pt`` → ``APG``; see :func:`paper_policy`). Anything else is reported the same
way, just without paper columns.

Plots use :class:`matplotlib.figure.Figure` with the Agg canvas: no pyplot, no global state.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import math
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from crossroads.evaluation.metrics import (
    ERROR,
    OUTCOMES,
    BatchSummary,
    PairedComparison,
    compare_paired,
    is_error,
    summarize,
    travel_times,
)
from crossroads.evaluation.paper import PAPER_CASE_TITLES, PAPER_CASES, PAPER_RUNS, PAPER_TABLE, PaperResult

PaperTable = Mapping[str, Mapping[str, PaperResult]]
TraceLink = Callable[[str, Any], "str | None"]

FAMILIES: tuple[str, ...] = ("overspeed", "rounding")
FAMILY_AXIS = {
    "overspeed": "overspeed: excess over the speed limit [%]",
    "rounding": "rounding: share of vehicles cutting in [%]",
}
COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf",
           "#7f7f7f", "#bcbd22")
PAPER_COLOURS = {"APG": "#1f77b4", "DPG": "#d62728"}

_CASE_RE = re.compile(r"(overspeed|rounding)[\s_+\-]*(\d+)", re.IGNORECASE)
_POLICY_RE = re.compile(r"(?<![a-z])(apg|dpg)(?![a-z])")


# --------------------------------------------------------------------------------------------------
# rows


def case_label(scenario: str) -> str | None:
    """The paper-style case of a scenario name: ``"overspeed-10"``, ``"rounding-50"``, or ``None``.

    The first ``overspeed``/``rounding`` followed by a number (separators ``-_+`` and spaces
    allowed) names it, so ``paper_overspeed_+20`` → ``overspeed-20``.
    """
    m = _CASE_RE.search(scenario)
    if m is None:
        return None
    return f"{m.group(1).lower()}-{int(m.group(2))}"


def split_case(case: str | None) -> tuple[str, int] | None:
    """``"overspeed-10"`` → ``("overspeed", 10)``; ``None`` for anything else."""
    if case is None:
        return None
    family, _, level = case.partition("-")
    if family not in FAMILIES or not level.isdigit():
        return None
    return family, int(level)


def paper_policy(policy: str) -> str | None:
    """The paper column a policy name stands for: ``"APG"``, ``"DPG"`` or ``None``.

    Matches ``apg``/``dpg`` as a word in the lower-cased name (``models/apg.pt``, ``dpg_seed3``).
    """
    m = _POLICY_RE.search(policy.lower())
    return m.group(1).upper() if m else None


@dataclass(frozen=True)
class FailedEpisode:
    """An episode that did not pass (``outcome`` ``error`` when it crashed)."""

    episode_id: Any  # the store's id (int or str); the seed where there is none
    seed: int
    outcome: str
    detail: str = ""
    trace: str | None = None  # trace file path (or store reference); None when none was recorded


@dataclass(frozen=True)
class BatchRow:
    """One batch of a report. ``case`` defaults to :func:`case_label` of the scenario name;
    ``warnings``: what its network gave reason to warn about when the batch was created (e.g.
    SUMO's internal lanes off the ego's paths), shown in the report so its numbers are read with it."""

    scenario: str
    policy: str
    batch_id: str
    summary: BatchSummary
    failed: list[FailedEpisode] = field(default_factory=list)
    travel_times: list[float] = field(default_factory=list)  # [s] of the passed episodes
    outcomes: dict[int, str] = field(default_factory=dict)  # seed → outcome ("error" if crashed)
    case: str | None = None
    warnings: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.case is None:
            object.__setattr__(self, "case", case_label(self.scenario))

    @property
    def paper_policy(self) -> str | None:
        return paper_policy(self.policy)

    def paper(self, table: PaperTable = PAPER_TABLE) -> PaperResult | None:
        """The paper's cell for this row's case and policy, if the paper has one."""
        col = self.paper_policy
        if self.case is None or col is None:
            return None
        return table.get(self.case, {}).get(col)

    @classmethod
    def from_results(cls, scenario: str, policy: str, batch_id: str, results: Iterable[Any], *,
                     confidence: float = 0.95, case: str | None = None,
                     warnings: Iterable[str] = ()) -> BatchRow:
        """A row from episode results (objects or mappings as in :mod:`crossroads.evaluation.metrics`).

        Failed episodes take their id from ``id``/``episode_id`` (else the seed), their detail from
        ``error`` (crashed) or ``detail``, their trace from ``trace_path``/``trace`` (a string).
        """
        items = list(results)
        failed: list[FailedEpisode] = []
        outcomes: dict[int, str] = {}
        for r in items:
            get = r.get if isinstance(r, Mapping) else (lambda k, d=None, _r=r: getattr(_r, k, d))
            seed = get("seed")
            errored = is_error(r)
            outcome = ERROR if errored else str(get("outcome"))
            if seed is not None:
                outcomes[int(seed)] = outcome
            if outcome == "passed":
                continue
            ep_id = get("id")
            if ep_id is None:
                ep_id = get("episode_id", seed)
            trace = get("trace_path") or get("trace")
            detail = (get("error") if errored else None) or get("detail") or ""
            failed.append(FailedEpisode(ep_id, -1 if seed is None else int(seed), outcome, str(detail),
                                        trace if isinstance(trace, str) else None))
        return cls(scenario=scenario, policy=policy, batch_id=str(batch_id),
                   summary=summarize(items, confidence), failed=failed,
                   travel_times=travel_times(items), outcomes=outcomes, case=case,
                   warnings=[str(w) for w in warnings])

    @classmethod
    def coerce(cls, row: BatchRow | Mapping[str, Any]) -> BatchRow:
        """A :class:`BatchRow` from itself or from a mapping of its fields (summary and failed
        episodes as mappings too)."""
        if isinstance(row, BatchRow):
            return row
        data = dict(row)
        summary = data["summary"]
        if isinstance(summary, Mapping):
            data["summary"] = BatchSummary.from_json(summary)
        data["failed"] = [f if isinstance(f, FailedEpisode) else FailedEpisode(**f)
                          for f in data.get("failed") or []]
        data["travel_times"] = [float(t) for t in data.get("travel_times") or []]
        data["outcomes"] = {int(k): str(v) for k, v in (data.get("outcomes") or {}).items()}
        data["batch_id"] = str(data["batch_id"])
        data["warnings"] = [str(w) for w in data.get("warnings") or []]
        return cls(**data)


# --------------------------------------------------------------------------------------------------
# layout helpers


def _esc(value: Any) -> str:
    return html.escape("" if value is None else str(value), quote=True)


def _pct(x: float | None, digits: int = 1) -> str:
    return "—" if x is None else f"{100.0 * x:.{digits}f} %"


def _num(x: float | None, digits: int = 2) -> str:
    return "—" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def _p(p: float) -> str:
    if p >= 0.001:
        return f"{p:.4f}".rstrip("0").rstrip(".") if p < 1 else "1"
    return f"{p:.1e}"


def _safe_href(href: str | None) -> str | None:
    """``href`` if it is relative or http(s)/file (or a drive letter); otherwise ``None``."""
    if not href:
        return None
    scheme = urlsplit(href).scheme.lower()
    if scheme in ("", "http", "https", "file") or len(scheme) == 1:
        return href
    return None


def _case_sort_key(row: BatchRow) -> tuple[int, int, str, int, str]:
    if row.case in PAPER_CASES:
        return (0, PAPER_CASES.index(row.case), "", 0, row.scenario)
    split = split_case(row.case)
    if split is not None:
        return (1, FAMILIES.index(split[0]), "", split[1], row.scenario)
    return (2, 0, row.scenario, 0, "")


def _row_title(row: BatchRow) -> str:
    if row.case in PAPER_CASE_TITLES and row.scenario == row.case:
        return PAPER_CASE_TITLES[row.case]
    return row.scenario


def _columns(rows: Sequence[BatchRow]) -> tuple[list[str], list[str]]:
    """A column label per row (its policy; a second batch of the same scenario and policy gets its
    batch id appended) and the column labels in order of first appearance."""
    seen: set[tuple[str, str]] = set()
    labels: list[str] = []
    for row in rows:
        label = row.policy
        if (row.scenario, label) in seen:
            label = f"{row.policy} [{row.batch_id}]"
        seen.add((row.scenario, label))
        labels.append(label)
    return labels, list(dict.fromkeys(labels))


def _colour_map(rows: Sequence[BatchRow], labels: Sequence[str], columns: Sequence[str]) -> dict[str, str]:
    """Colours per column: a column standing for APG/DPG takes the paper's colour for it (the
    first such column only), the others the next free colour."""
    colours: dict[str, str] = {}
    used: set[str] = set()
    by_label = {lab: row for lab, row in zip(labels, rows)}
    for col in columns:
        pp = by_label[col].paper_policy
        if pp in PAPER_COLOURS and PAPER_COLOURS[pp] not in used:
            colours[col] = PAPER_COLOURS[pp]
            used.add(colours[col])
    free = [c for c in COLOURS if c not in used and c not in PAPER_COLOURS.values()]
    for i, col in enumerate(c for c in columns if c not in colours):
        colours[col] = free[i % len(free)]
    return colours


# --------------------------------------------------------------------------------------------------
# plots


def figure_png(fig: Figure, dpi: int = 110) -> bytes:
    """PNG bytes of a figure, drawn with the Agg canvas."""
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return buf.getvalue()


def _img(fig: Figure, alt: str) -> str:
    data = base64.b64encode(figure_png(fig)).decode("ascii")
    return f'<img class="plot" alt="{_esc(alt)}" src="data:image/png;base64,{data}">'


def pass_rate_figure(rows: Iterable[BatchRow | Mapping[str, Any]], *,
                     paper: PaperTable = PAPER_TABLE) -> Figure | None:
    """Pass rate [%] against the injection level, one panel per family (overspeed, rounding) that
    the rows have, one line per policy with Wilson-interval error bars; the paper's points for
    the same family drawn hollow and dashed. ``None`` when no row names such a case."""
    rows = [BatchRow.coerce(r) for r in rows]
    labels, columns = _columns(rows)
    colours = _colour_map(rows, labels, columns)
    families = [f for f in FAMILIES if any((split_case(r.case) or ("",))[0] == f for r in rows)]
    if not families:
        return None
    fig = Figure(figsize=(5.2 * len(families), 4.0), layout="constrained")
    axes = fig.subplots(1, len(families), squeeze=False)[0]
    n_cols = max(1, len(columns))
    for ax, family in zip(axes, families):
        levels: set[int] = set()
        for ci, col in enumerate(columns):
            pts = sorted(
                ((split[1], row.summary) for lab, row in zip(labels, rows)
                 if lab == col and (split := split_case(row.case)) is not None and split[0] == family
                 and row.summary.pass_rate is not None), key=lambda t: t[0])
            if not pts:
                continue
            dx = (ci - (n_cols - 1) / 2) * 0.7
            xs = [lv + dx for lv, _ in pts]
            ys = [100 * s.pass_rate for _, s in pts]
            err = [[100 * (s.pass_rate - s.wilson_low) for _, s in pts],
                   [100 * (s.wilson_high - s.pass_rate) for _, s in pts]]
            ax.errorbar(xs, ys, yerr=err, color=colours[col], marker="o", ms=6, lw=1.6, capsize=4,
                        label=col)
            levels.update(lv for lv, _ in pts)
        # the paper's points, hollow
        mapped = {}
        for lab, row in zip(labels, rows):
            if row.paper_policy is not None and row.paper_policy not in mapped:
                mapped[row.paper_policy] = colours[lab]
        pols = sorted({p for case in paper.values() for p in case})
        for pi, pol in enumerate(pols):
            pts2 = sorted((split[1], cell[pol].pass_rate) for case, cell in paper.items()
                          if (split := split_case(case)) is not None and split[0] == family and pol in cell)
            if not pts2:
                continue
            dx = (pi - (len(pols) - 1) / 2) * 0.7
            colour = mapped.get(pol, PAPER_COLOURS.get(pol, "#444444"))
            ax.plot([lv + dx for lv, _ in pts2], [100 * r for _, r in pts2], ls="--", lw=1.0,
                    color=colour, marker="o" if pol == "APG" else "s", ms=8, mfc="none", mew=1.6,
                    label=f"paper {pol}")
            levels.update(lv for lv, _ in pts2)
        ax.set_title(family)
        ax.set_xlabel(FAMILY_AXIS[family])
        ax.set_ylabel("pass rate [%] (95 % Wilson interval)")
        if levels:
            ax.set_xticks(sorted(levels))
            ax.set_xlim(min(levels) - 5, max(levels) + 5)
            ax.legend(fontsize=8, loc="best")
        lo = min(ax.get_ylim()[0], 80.0)
        ax.set_ylim(max(0.0, lo - 2.0), 102.0)
        ax.grid(True, alpha=0.3)
    return fig


def travel_time_figure(rows: Iterable[BatchRow | Mapping[str, Any]], *,
                       paper: PaperTable = PAPER_TABLE) -> Figure | None:
    """Box plots of the passed episodes' travel times, grouped by case (scenario) with one box per
    policy; the paper's mean ± std beside a box as a hollow marker with a bar. ``None`` when no
    row has travel times."""
    rows = sorted((BatchRow.coerce(r) for r in rows), key=_case_sort_key)
    labels, columns = _columns(rows)
    colours = _colour_map(rows, labels, columns)
    if not any(r.travel_times for r in rows):
        return None
    groups = list(dict.fromkeys(r.scenario for r in rows))
    n_cols = len(columns)
    width = 0.8 / max(1, n_cols)
    fig = Figure(figsize=(max(6.0, 0.45 * len(groups) * max(2, n_cols) + 1.5), 4.2), layout="constrained")
    ax = fig.subplots()
    paper_drawn: set[str] = set()
    for gi, scen in enumerate(groups):
        for lab, row in zip(labels, rows):
            if row.scenario != scen:
                continue
            ci = columns.index(lab)
            x = gi + (ci - (n_cols - 1) / 2) * width
            if row.travel_times:
                bp = ax.boxplot([row.travel_times], positions=[x], widths=width * 0.6, patch_artist=True,
                                manage_ticks=False, flierprops={"ms": 3, "mec": colours[lab]},
                                medianprops={"color": "black"})
                for patch in bp["boxes"]:
                    patch.set_facecolor(colours[lab])
                    patch.set_alpha(0.55)
            cell = row.paper(paper)
            if cell is not None:
                ax.errorbar([x + width * 0.38], [cell.travel_mean_s], yerr=[cell.travel_std_s],
                            color=colours[lab], marker="D", ms=6, mfc="white", mew=1.5, capsize=3,
                            lw=1.0, ls="none")
                paper_drawn.add(lab)
    ax.set_xticks(range(len(groups)))
    titles = {r.scenario: _row_title(r) for r in rows}
    ax.set_xticklabels([titles[g] for g in groups], rotation=20 if len(groups) > 4 else 0, ha="right"
                       if len(groups) > 4 else "center", fontsize=8)
    ax.set_xlim(-0.6, len(groups) - 0.4)
    ax.set_ylabel("travel time [s] (passed episodes)")
    ax.grid(True, axis="y", alpha=0.3)
    handles = [Line2D([], [], color=colours[c], lw=8, alpha=0.55, label=c) for c in columns]
    if paper_drawn:
        handles.append(Line2D([], [], color="#444444", marker="D", mfc="white", ls="none",
                              label="paper mean ± std"))
    ax.legend(handles=handles, fontsize=8, loc="upper left")
    return fig


# --------------------------------------------------------------------------------------------------
# HTML

_CSS = """
body{font-family:-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:2em auto;max-width:1200px;
color:#222;padding:0 1em}
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:2em;border-bottom:1px solid #ddd;padding-bottom:.2em}
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}
th,td{border:1px solid #ccc;padding:.25em .55em;text-align:right;vertical-align:top}
th{background:#f3f3f3}td.l,th.l{text-align:left}
td.paper,th.paper{background:#f7f7fb;color:#555}
.off{color:#b00020;font-weight:600}.muted{color:#777;font-size:.85em}
.sig{font-weight:700}img.plot{max-width:100%;border:1px solid #eee;margin:.5em 0}
details{margin:.4em 0}summary{cursor:pointer}code{font-size:.9em}
.warnings{background:#fff8e6;border-left:4px solid #d9a400;padding:.2em 1em;margin:1em 0}
.warnings h2{margin-top:.6em;border:0}.warnings table{background:#fff}
"""


def _rate_cell(s: BatchSummary) -> str:
    if s.pass_rate is None:
        return '<td>—<div class="muted">no valid runs</div></td>'
    extra = (f"n={s.valid}" + (f", {s.errors} err" if s.errors else "")
             + (f", blocked by the world: {s.blocked}" if s.blocked else ""))
    return (f"<td>{_pct(s.pass_rate)} <span class=\"muted\">[{_pct(s.wilson_low)}, "
            f"{_pct(s.wilson_high)}]</span><div class=\"muted\">{_esc(extra)}</div></td>")


def _travel_cell(s: BatchSummary) -> str:
    if s.travel_mean_s is None:
        return "<td>—</td>"
    return (f"<td>{_num(s.travel_mean_s)} ± {_num(s.travel_std_s)}"
            f"<div class=\"muted\">n={s.travel_n}</div></td>")


def _main_table(rows: Sequence[BatchRow], labels: Sequence[str], columns: Sequence[str],
                paper: PaperTable) -> str:
    by_cell = {(row.scenario, lab): row for lab, row in zip(labels, rows)}
    scenarios = list(dict.fromkeys(r.scenario for r in sorted(rows, key=_case_sort_key)))
    first = {r.scenario: r for r in rows}
    with_paper = {lab for lab, row in zip(labels, rows) if row.paper(paper) is not None}
    head1 = ['<th class="l" rowspan="2">case</th>']
    head2 = []
    for col in columns:
        span = 4 if col in with_paper else 2
        sample = next(row for lab, row in zip(labels, rows) if lab == col)
        pp = f' <span class="muted">(paper: {_esc(sample.paper_policy)})</span>' if col in with_paper else ""
        head1.append(f'<th colspan="{span}">{_esc(col)}{pp}</th>')
        head2.append("<th>pass rate [95 % CI]</th>")
        if col in with_paper:
            head2.append('<th class="paper">paper</th>')
        head2.append("<th>travel time [s]</th>")
        if col in with_paper:
            head2.append('<th class="paper">paper</th>')
    body = []
    for scen in scenarios:
        row0 = first[scen]
        sub = f'<div class="muted">{_esc(scen)}</div>' if _row_title(row0) != scen else ""
        cells = [f'<td class="l">{_esc(_row_title(row0))}{sub}</td>']
        for col in columns:
            row = by_cell.get((scen, col))
            span = 4 if col in with_paper else 2
            if row is None:
                cells.extend(["<td>—</td>"] * span)
                continue
            cell = row.paper(paper)
            cells.append(_rate_cell(row.summary))
            if col in with_paper:
                if cell is None:
                    cells.append('<td class="paper">—</td>')
                else:
                    s = row.summary
                    outside = s.pass_rate is not None and not (s.wilson_low <= cell.pass_rate <= s.wilson_high)
                    cls = "paper off" if outside else "paper"
                    tip = (' title="the paper\'s rate lies outside our 95 % interval"' if outside else "")
                    cells.append(f'<td class="{cls}"{tip}>{_pct(cell.pass_rate, 0)}</td>')
            cells.append(_travel_cell(row.summary))
            if col in with_paper:
                cells.append('<td class="paper">—</td>' if cell is None else
                             f'<td class="paper">{_num(cell.travel_mean_s)} ± {_num(cell.travel_std_s)}</td>')
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (f"<table><thead><tr>{''.join(head1)}</tr><tr>{''.join(head2)}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table>")


def _paper_table(paper: PaperTable, cases: Sequence[str]) -> str:
    pols = sorted({p for c in cases for p in paper.get(c, {})})
    head = '<th class="l">case</th>' + "".join(f'<th colspan="2">{_esc(p)}</th>' for p in pols)
    body = []
    for case in cases:
        cells = [f'<td class="l">{_esc(PAPER_CASE_TITLES.get(case, case))}</td>']
        for p in pols:
            cell = paper.get(case, {}).get(p)
            if cell is None:
                cells.append("<td>—</td><td>—</td>")
            else:
                cells.append(f"<td>{_pct(cell.pass_rate, 0)}</td>"
                             f"<td>{_num(cell.travel_mean_s)} ± {_num(cell.travel_std_s)} s</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def paired_comparisons(rows: Iterable[BatchRow | Mapping[str, Any]]
                       ) -> list[tuple[BatchRow, BatchRow, PairedComparison]]:
    """Every pair of batches of one scenario by two different policies that both carry outcomes
    per seed, with their exact McNemar comparison (A = the earlier row)."""
    rows = [BatchRow.coerce(r) for r in rows]
    out = []
    for i, a in enumerate(rows):
        for b in rows[i + 1:]:
            if a.scenario != b.scenario or a.policy == b.policy or not a.outcomes or not b.outcomes:
                continue
            comp = compare_paired([{"seed": s, "outcome": o} for s, o in a.outcomes.items()],
                                  [{"seed": s, "outcome": o} for s, o in b.outcomes.items()])
            out.append((a, b, comp))
    return out


def _paired_table(pairs: Sequence[tuple[BatchRow, BatchRow, PairedComparison]]) -> str:
    head = ("<tr><th class=\"l\">case</th><th class=\"l\">A</th><th class=\"l\">B</th><th>pairs</th>"
            "<th>A pass</th><th>B pass</th><th>both pass</th><th>only A passes</th>"
            "<th>only B passes</th><th>both fail</th><th>McNemar exact p</th></tr>")
    body = []
    for a, b, c in sorted(pairs, key=lambda t: _case_sort_key(t[0])):
        sig = ' class="sig"' if c.p_value < 0.05 else ""
        body.append(
            f'<tr><td class="l">{_esc(_row_title(a))}</td><td class="l">{_esc(a.policy)}'
            f'<div class="muted">batch {_esc(a.batch_id)}</div></td><td class="l">{_esc(b.policy)}'
            f'<div class="muted">batch {_esc(b.batch_id)}</div></td><td>{c.pairs}</td><td>{_pct(c.a_pass_rate)}</td>'
            f"<td>{_pct(c.b_pass_rate)}</td><td>{c.both_passed}</td><td>{c.b10}</td><td>{c.b01}</td>"
            f"<td>{c.both_failed}</td><td{sig}>{_p(c.p_value)}</td></tr>")
    return f"<table><thead>{head}</thead><tbody>{''.join(body)}</tbody></table>"


def _outcome_keys(rows: Sequence[BatchRow]) -> list[str]:
    keys = list(OUTCOMES) + [ERROR]
    for r in rows:
        keys.extend(k for k in r.summary.outcomes if k not in keys)
    return keys


def _batch_table(rows: Sequence[BatchRow]) -> str:
    keys = _outcome_keys(rows)
    head = ('<tr><th class="l">batch</th><th class="l">scenario</th><th class="l">policy</th><th>runs</th>'
            + "".join(f"<th>{_esc(k)}</th>" for k in keys)
            + "<th>pass rate [95 % CI]</th><th>travel time [s]</th></tr>")
    body = []
    for r in sorted(rows, key=_case_sort_key):
        s = r.summary
        body.append(
            f'<tr><td class="l"><code>{_esc(r.batch_id)}</code></td><td class="l">{_esc(r.scenario)}</td>'
            f'<td class="l">{_esc(r.policy)}</td><td>{s.runs}</td>'
            + "".join(f"<td>{s.outcomes.get(k, 0)}</td>" for k in keys)
            + _rate_cell(s) + _travel_cell(s) + "</tr>")
    return f"<table><thead>{head}</thead><tbody>{''.join(body)}</tbody></table>"


def _warnings_section(rows: Sequence[BatchRow]) -> str:
    """Every batch's warnings, one line each; empty when no batch has any."""
    lines = [(r, w) for r in sorted(rows, key=_case_sort_key) for w in r.warnings]
    if not lines:
        return ""
    body = "".join(f'<tr><td class="l"><code>{_esc(r.batch_id)}</code></td><td class="l">{_esc(r.scenario)}</td>'
                   f'<td class="l">{_esc(r.policy)}</td><td class="l">{_esc(w)}</td></tr>' for r, w in lines)
    return ('<section class="warnings"><h2>Warnings</h2>'
            '<p class="muted">Recorded when each batch was created, from its network as it was then: '
            "the batch ran, but read its numbers with these in mind.</p>"
            '<table><thead><tr><th class="l">batch</th><th class="l">scenario</th><th class="l">policy</th>'
            f'<th class="l">warning</th></tr></thead><tbody>{body}</tbody></table></section>')


def _failed_section(rows: Sequence[BatchRow], trace_link: TraceLink | None) -> str:
    parts = []
    for r in sorted(rows, key=_case_sort_key):
        if not r.failed:
            continue
        body = []
        for ep in r.failed:
            href = None
            if ep.trace is not None:
                href = _safe_href(trace_link(r.batch_id, ep.episode_id) if trace_link else ep.trace)
            link = f'<a href="{_esc(href)}">trace</a>' if href else '<span class="muted">none</span>'
            body.append(f"<tr><td>{_esc(ep.episode_id)}</td><td>{_esc(ep.seed)}</td>"
                        f'<td class="l">{_esc(ep.outcome)}</td><td class="l">{_esc(ep.detail)}</td>'
                        f'<td class="l">{link}</td></tr>')
        opened = " open" if len(r.failed) <= 10 else ""
        parts.append(
            f"<details{opened}><summary>{_esc(r.scenario)} · {_esc(r.policy)} · batch "
            f"<code>{_esc(r.batch_id)}</code>: {len(r.failed)} failed</summary>"
            '<table><thead><tr><th>episode</th><th>seed</th><th class="l">outcome</th>'
            '<th class="l">detail</th><th class="l">trace</th></tr></thead>'
            f"<tbody>{''.join(body)}</tbody></table></details>")
    return "".join(parts) if parts else "<p>No failed episodes.</p>"


def render_html(rows: Iterable[BatchRow | Mapping[str, Any]], *, title: str = "Crossroads evaluation",
                paper: PaperTable = PAPER_TABLE, trace_link: TraceLink | None = None) -> str:
    """The report as one self-contained HTML document (inline CSS, plots as base64 PNG).

    ``trace_link(batch_id, episode_id)`` gives the href of a failed episode's trace (``None``: no
    link); it is asked only for episodes that have a trace. Without it, the trace path itself is
    the href. Links with a scheme other than http(s)/file are dropped; all text is escaped.
    """
    rows = [BatchRow.coerce(r) for r in rows]
    labels, columns = _columns(rows)
    out = ["<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">",
           f"<title>{_esc(title)}</title><style>{_CSS}</style></head><body>",
           f"<h1>{_esc(title)}</h1>"]
    if not rows:
        out.append("<p>No batches.</p></body></html>")
        return "".join(out)
    n_runs = sum(r.summary.runs for r in rows)
    n_err = sum(r.summary.errors for r in rows)
    out.append(f"<p>{len(rows)} batch{'es' if len(rows) != 1 else ''}, {n_runs} episodes"
               f"{f', {n_err} errored (left out of the pass rates)' if n_err else ''}; "
               f"policies: {', '.join(_esc(c) for c in columns)}.</p>")
    if warnings := _warnings_section(rows):
        out.append(warnings)

    out.append("<h2>Results</h2>")
    out.append("<p class=\"muted\">Pass rate = passed / (runs − errored) with its Wilson 95 % interval "
               "(\"blocked by the world\": timeouts behind a participant that stood across every "
               "candidate path the whole episode, counted in the rate and named apart); "
               "travel time (stop line → leaving the intersection, passed episodes) mean ± sample std. "
               "Paper columns (SPEC §8, 200 runs per case) appear where the case and policy match; "
               "a paper rate in <span class=\"off\">red</span> lies outside our interval.</p>")
    out.append(_main_table(rows, labels, columns, paper))
    cases = [c for c in PAPER_CASES if any(r.case == c for r in rows) and c in paper]
    if cases:
        out.append(f"<h3>The paper's numbers (Sec. V-C; {PAPER_RUNS} runs per case)</h3>")
        out.append(_paper_table(paper, cases))

    fig = pass_rate_figure(rows, paper=paper)
    if fig is not None:
        out.append("<h2>Pass rate against the injection level</h2>")
        out.append("<p class=\"muted\">Filled markers: measured, bars the Wilson 95 % interval; hollow "
                   "markers and dashed lines: the paper.</p>")
        out.append(_img(fig, "pass rate against the injection level"))
    fig = travel_time_figure(rows, paper=paper)
    if fig is not None:
        out.append("<h2>Travel-time distributions</h2>")
        out.append("<p class=\"muted\">Boxes: quartiles and median of the passed episodes, whiskers "
                   "1.5 IQR; hollow diamonds: the paper's mean ± std.</p>")
        out.append(_img(fig, "travel-time distributions"))

    pairs = paired_comparisons(rows)
    if pairs:
        out.append("<h2>Paired comparisons</h2>")
        out.append("<p class=\"muted\">Two policies on the same seeds (seeds both ran, neither errored); "
                   "exact two-sided McNemar test on the discordant pairs; p &lt; 0.05 in bold.</p>")
        out.append(_paired_table(pairs))

    out.append("<h2>Batches and outcomes</h2>")
    out.append(_batch_table(rows))
    out.append("<h2>Failed episodes</h2>")
    out.append(_failed_section(rows, trace_link))
    out.append("</body></html>")
    return "\n".join(out)


# --------------------------------------------------------------------------------------------------
# CSV

CSV_FIELDS: tuple[str, ...] = (
    "batch_id", "scenario", "case", "policy", "runs", "errors", "valid", "passed", "blocked", "pass_rate",
    "wilson_low", "wilson_high", "confidence", "travel_mean_s", "travel_std_s", "travel_n",
    "warnings",  # the batch's warnings joined with "; " (empty: none)
)
PAPER_CSV_FIELDS: tuple[str, ...] = ("paper_policy", "paper_pass_rate", "paper_travel_mean_s",
                                     "paper_travel_std_s")


def _csv_value(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)  # round-trips exactly through float()
    return str(v)


def csv_rows(rows: Iterable[BatchRow | Mapping[str, Any]], *,
             paper: PaperTable = PAPER_TABLE) -> tuple[list[str], list[dict[str, str]]]:
    """The CSV's header and lines (one per batch): :data:`CSV_FIELDS`, ``outcome_<name>`` per
    outcome, then :data:`PAPER_CSV_FIELDS` (empty where the paper has no cell)."""
    rows = [BatchRow.coerce(r) for r in rows]
    keys = _outcome_keys(rows)
    header = [*CSV_FIELDS, *(f"outcome_{k}" for k in keys), *PAPER_CSV_FIELDS]
    lines = []
    for r in rows:
        s = r.summary
        cell = r.paper(paper)
        values: dict[str, Any] = {
            "batch_id": r.batch_id, "scenario": r.scenario, "case": r.case, "policy": r.policy,
            "runs": s.runs, "errors": s.errors, "valid": s.valid, "passed": s.passed,
            "blocked": s.blocked,
            "pass_rate": s.pass_rate, "wilson_low": s.wilson_low, "wilson_high": s.wilson_high,
            "confidence": s.confidence, "travel_mean_s": s.travel_mean_s, "travel_std_s": s.travel_std_s,
            "travel_n": s.travel_n, "warnings": "; ".join(r.warnings),
            **{f"outcome_{k}": s.outcomes.get(k, 0) for k in keys},
            "paper_policy": r.paper_policy if cell else None,
            "paper_pass_rate": cell.pass_rate if cell else None,
            "paper_travel_mean_s": cell.travel_mean_s if cell else None,
            "paper_travel_std_s": cell.travel_std_s if cell else None,
        }
        lines.append({k: _csv_value(values[k]) for k in header})
    return header, lines


def write_csv(rows: Iterable[BatchRow | Mapping[str, Any]], path: str | Path, *,
              paper: PaperTable = PAPER_TABLE) -> Path:
    """Write :func:`csv_rows` to ``path`` (UTF-8); returns the path."""
    header, lines = csv_rows(rows, paper=paper)
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=header)
        writer.writeheader()
        writer.writerows(lines)
    return path
