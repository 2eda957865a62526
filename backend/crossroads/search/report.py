"""A search's report: which parameters drive the failures.

One panel per parameter, every episode the search proposed as a point: the parameter's value
against the episode's objective (failures at −1, near misses just above 0, comfortable episodes
at 1), coloured by outcome, with the share of failing episodes in each fifth of the range (of the
values, for choices) drawn over it. A parameter that drives the failures shows them piling up at
one end. Then the failures kept, shrunk, with what each still needs off nominal.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from crossroads.evaluation.report import figure_png
from crossroads.search import records
from crossroads.search.engine import summarize_search
from crossroads.search.objective import FAILURE_VALUE
from crossroads.search.space import Parameter, Space
from crossroads.store import Store

OUTCOME_COLOURS = {"passed": "#2ca02c", "timeout": "#7f7f7f", "collision": "#d62728",
                   "red_light": "#ff7f0e", "off_road": "#9467bd", "error": "#000000"}
BINS = 5


def _esc(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _failure_share(values: np.ndarray, failed: np.ndarray, p: Parameter) -> tuple[list[float], list[float]]:
    """(bin centres, share of failures) over the parameter's range or choices."""
    if p.choices is not None:
        xs = sorted(float(c) for c in p.choices)
        return xs, [float(failed[values == x].mean()) if (values == x).any() else float("nan") for x in xs]
    edges = np.linspace(float(p.low), float(p.high), BINS + 1)  # type: ignore[arg-type]
    index = np.clip(np.digitize(values, edges[1:-1]), 0, BINS - 1)
    centres = list((edges[:-1] + edges[1:]) / 2.0)
    return centres, [float(failed[index == b].mean()) if (index == b).any() else float("nan")
                     for b in range(BINS)]


def parameter_figure(space: Space, trials: Sequence[Mapping[str, Any]]) -> Figure:
    """The panels (see the module docstring); ``trials``: dicts with params, outcome, objective."""
    params = space.parameters
    cols = min(3, len(params))
    rows = (len(params) + cols - 1) // cols
    fig = Figure(figsize=(4.2 * cols, 3.0 * rows))
    done = [t for t in trials if t["objective"] is not None]
    nominal = space.nominal_values()
    for i, p in enumerate(params):
        ax = fig.add_subplot(rows, cols, i + 1)
        values = np.array([float(t["params"][p.path]) for t in done])
        scores = np.array([float(t["objective"]) for t in done])
        failed = scores == FAILURE_VALUE
        for outcome, colour in OUTCOME_COLOURS.items():
            mask = np.array([t["outcome"] == outcome for t in done], dtype=bool)
            if mask.any():
                ax.scatter(values[mask], scores[mask], s=9, c=colour, alpha=0.6, label=outcome,
                           linewidths=0)
        ax.axvline(float(nominal[p.path]), color="#444444", lw=0.8, ls=":")
        ax.set_title(p.path, fontsize=9)
        ax.set_ylim(-1.1, 1.1)
        ax.set_ylabel("objective", fontsize=8)
        ax.tick_params(labelsize=7)
        if len(values):
            share = ax.twinx()
            xs, ys = _failure_share(values, failed, p)
            share.plot(xs, ys, color="#d62728", lw=1.2, marker="o", ms=3)
            share.set_ylim(0.0, 1.0)
            share.set_ylabel("failing share", fontsize=8, color="#d62728")
            share.tick_params(labelsize=7, colors="#d62728")
        if i == 0:
            ax.legend(fontsize=6, loc="upper right", markerscale=1.5)
    fig.suptitle("Outcome against each parameter (dotted: nominal; red line: share failing)", fontsize=10)
    fig.tight_layout()
    return fig


def _moved(failure: Mapping[str, Any]) -> str:
    """The parameters a failure still needs off nominal, with their values."""
    params = failure["params"]
    return ", ".join(f"{k} = {params[k]:g}" for k in failure["off_nominal"]) or "nominal"


def render_html(store: Store, search_id: int) -> str:
    """The report of a stored search as one self-contained HTML document."""
    from crossroads.search.engine import stored_space

    summary = summarize_search(store, search_id)
    with store.session() as session:
        search = records.get_search(session=session, search_id=search_id)
        assert search is not None
        space = stored_space(search.space, search_id)
        trials = [{"params": t.params, "outcome": t.outcome, "objective": t.objective}
                  for t in records.trials(session=session, search_id=search_id, kind="search")
                  if t.outcome is not None]
    png = base64.b64encode(figure_png(parameter_figure(space, trials))).decode("ascii")
    outcomes = ", ".join(f"{k} {v}" for k, v in sorted(summary["outcomes"].items())) or "none"
    rows = "".join(
        f"<tr><td>{_esc(f['name'])}</td><td>{_esc(f['outcome'])}</td><td>{f['seed']}</td>"
        f"<td>{f['distance']:.3f}</td><td>{_esc(_moved(f))}</td>"
        f"<td><code>{_esc(f['yaml_path'] or '')}</code></td></tr>"
        for f in summary["failure_list"])
    best = "n/a" if summary["best_objective"] is None else f"{summary['best_objective']:.3f}"
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Search {search_id}: {_esc(summary['name'])}</title>
<style>body{{font-family:system-ui,sans-serif;margin:2em;max-width:1300px}}
table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:3px 8px;font-size:13px}}
img{{max-width:100%}}</style></head><body>
<h1>Failure search {search_id}: {_esc(summary['name'])} × {_esc(summary['policy'])}</h1>
<p>Sampler <b>{_esc(summary['sampler'])}</b>, seed {summary['seed']}, status {_esc(summary['status'])}:
{summary['searched']} of {summary['budget']} episodes ({_esc(outcomes)}); best objective {best}.
Failing episodes {summary['failing']}; failures kept {summary['failures']}
({summary['distinct_failures']} distinct, {summary['failure_modes']} modes: outcome and the parameters
still off nominal) after {summary['shrink_episodes']} shrinking episodes.</p>
<h2>Which parameters drive the failures</h2>
<img alt="outcome against each parameter" src="data:image/png;base64,{png}">
<h2>Failures (shrunk)</h2>
<table><tr><th>scenario</th><th>outcome</th><th>seed</th><th>distance from nominal</th>
<th>still off nominal</th><th>file</th></tr>{rows}</table>
<p>Replay one: <code>crossroads evaluate FILE --policy {_esc(summary['policy'])}</code>.</p>
</body></html>
"""


def write_report(store: Store, search_id: int, out: str | Path) -> Path:
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(render_html(store, search_id), encoding="utf-8")
    return out
