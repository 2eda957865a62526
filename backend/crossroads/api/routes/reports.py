"""Reports over any set of stored batches: the HTML report or its CSV."""

from __future__ import annotations

import csv
import io
from typing import Annotated, Literal

from fastapi import APIRouter, HTTPException, Query
from fastapi.responses import HTMLResponse, Response
from pydantic import Field

from crossroads.api.deps import StoreDep
from crossroads.evaluation.report import csv_rows, render_html
from crossroads.store.reporting import UnknownBatchError, report_rows
from crossroads.store.tables import MAX_ROW_ID

router = APIRouter(prefix="/reports", tags=["reports"])

MAX_REPORT_BATCHES = 50  # batches one report compares


def _trace_link(batch_id: str, episode_id: int | str) -> str:
    return f"/api/episodes/{batch_id}/{episode_id}/trace"


@router.get("", response_class=Response,
            responses={200: {"content": {"text/html": {}, "text/csv": {}}}})
def report(
    store: StoreDep,
    batch: Annotated[list[Annotated[int, Field(ge=1, le=MAX_ROW_ID)]], Query(
        min_length=1, max_length=MAX_REPORT_BATCHES, description="batch ids (repeat: ?batch=1&batch=2)")],
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
