"""Reports over any set of stored batches: the HTML report or its CSV, and the paired comparison
of any batches the user picks (``GET /reports/comparison``, JSON for the studio's charts)."""

from __future__ import annotations

import csv
import io
from typing import Annotated, Literal

from itertools import combinations
from typing import Any

from fastapi import APIRouter, HTTPException, Query
from fastapi.responses import HTMLResponse, Response
from pydantic import Field

from crossroads.api.deps import SessionDep, StoreDep
from crossroads.evaluation.metrics import compare_paired, is_error, is_passed, wilson_interval
from crossroads.evaluation.report import csv_rows, render_html
from crossroads.evaluation.stored_batches import UnknownBatchError, report_rows
from crossroads.store import crud
from crossroads.store.tables import MAX_ROW_ID, Episode

router = APIRouter(prefix="/reports", tags=["reports"])

MAX_REPORT_BATCHES = 50  # batches one report compares
MAX_COMPARED_BATCHES = 8  # batches one comparison pairs (every pair of them)
BatchIds = Annotated[list[Annotated[int, Field(ge=1, le=MAX_ROW_ID)]], Query(
    min_length=1, max_length=MAX_REPORT_BATCHES, description="batch ids (repeat: ?batch=1&batch=2)")]
ComparedIds = Annotated[list[Annotated[int, Field(ge=1, le=MAX_ROW_ID)]], Query(
    min_length=2, max_length=MAX_COMPARED_BATCHES, description="two or more batch ids (?batch=1&batch=2)")]


def _trace_link(batch_id: str, episode_id: int | str) -> str:
    return f"/api/episodes/{batch_id}/{episode_id}/trace"


@router.get("", response_class=Response,
            responses={200: {"content": {"text/html": {}, "text/csv": {}}}})
def report(
    store: StoreDep,
    batch: BatchIds,
    format: Annotated[Literal["html", "csv"], Query()] = "html",  # noqa: A002 - the query's name
    title: Annotated[str, Query(max_length=200)] = "Crossroads evaluation",
) -> Response:
    """The report of the given batches (pass rates with Wilson intervals, travel times, paired
    comparisons, failed episodes)."""
    try:
        rows = report_rows(store, list(dict.fromkeys(batch)))
    except UnknownBatchError as exc:
        raise HTTPException(status_code=404, detail=str(exc)) from exc
    if format == "html":
        return HTMLResponse(render_html(rows, title=title, trace_link=_trace_link))
    header, lines = csv_rows(rows)
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=header)
    writer.writeheader()
    writer.writerows(lines)
    return Response(out.getvalue(), media_type="text/csv",
                    headers={"Content-Disposition": 'attachment; filename="crossroads-report.csv"'})


def _batch_figures(batch: Any, episodes: list[Episode]) -> dict[str, Any]:
    """A batch's pass rate over its judged (not errored) episodes, with its Wilson 95 % interval."""
    judged = [e for e in episodes if not is_error(e)]
    passed = sum(is_passed(e) for e in judged)
    low, high = wilson_interval(passed, len(judged)) if judged else (None, None)
    return {"id": batch.id, "scenario": batch.scenario.name, "scenario_id": batch.scenario_id,
            "policy": batch.policy.name, "status": batch.status, "recorded": len(episodes),
            "judged": len(judged), "passed": passed,
            "pass_rate": passed / len(judged) if judged else None, "wilson_low": low, "wilson_high": high}


def _seed_rows(a: list[Episode], b: list[Episode]) -> list[dict[str, Any]]:
    """The seeds both batches ran, each with both outcomes and travel times (B − A where both passed)."""
    by_seed = {e.seed: e for e in a}
    rows = []
    for eb in sorted((e for e in b if e.seed in by_seed), key=lambda e: e.seed):
        ea = by_seed[eb.seed]
        pa, pb = is_passed(ea), is_passed(eb)
        diff = "both pass" if pa and pb else "only A passes" if pa else "only B passes" if pb else "both fail"
        if is_error(ea) or is_error(eb):
            diff = "error (not paired)"
        both = ea.travel_time_s is not None and eb.travel_time_s is not None
        rows.append({"seed": eb.seed, "a_run": ea.run_index, "b_run": eb.run_index,
                     "a_outcome": ea.outcome, "b_outcome": eb.outcome, "difference": diff,
                     "a_travel_time_s": ea.travel_time_s, "b_travel_time_s": eb.travel_time_s,
                     "travel_time_diff_s": eb.travel_time_s - ea.travel_time_s if both else None})
    return rows


@router.get("/comparison")
def comparison(session: SessionDep, batch: ComparedIds) -> dict[str, Any]:
    """Any batches compared: each one's pass rate with its Wilson 95 % interval, and every pair of
    them paired on the seeds both ran (neither errored): the counts, the exact McNemar p (two-sided),
    and the per-seed outcomes and travel-time differences (B − A). A is the earlier id of a pair."""
    ids = sorted(dict.fromkeys(batch))
    if len(ids) < 2:
        raise HTTPException(status_code=422, detail=[{"loc": ["query", "batch"], "type": "value_error",
                                                      "msg": "give two different batches or more"}])
    rows, episodes = [], {}
    for batch_id in ids:
        row = crud.get_batch(session=session, batch_id=batch_id)
        if row is None:
            raise HTTPException(status_code=404, detail=f"no batch {batch_id}")
        episodes[batch_id] = crud.batch_results(session=session, batch_id=batch_id)
        rows.append(_batch_figures(row, episodes[batch_id]))
    pairs = []
    for a, b in combinations(ids, 2):
        paired = compare_paired(episodes[a], episodes[b]).to_json()
        pairs.append({"a": a, "b": b, **paired, "seeds": _seed_rows(episodes[a], episodes[b])})
    return {"batches": rows, "pairs": pairs}
