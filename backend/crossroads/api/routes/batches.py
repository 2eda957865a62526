"""Batches: start (202; it runs in the background), list, read with progress (elapsed time, rate,
ETA) and summary, cancel, resume an interrupted one, progress as Server-Sent Events, and the
episodes of a batch."""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator
from datetime import UTC, datetime
from typing import Annotated, Any

from fastapi import APIRouter, Depends, HTTPException, Query, Request, Response, status
from fastapi.responses import StreamingResponse
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from crossroads.api.deps import (
    JobsDep,
    OptionsDep,
    SessionDep,
    SettingsDep,
    StoreDep,
    unprocessable,
)
from crossroads.api.jobs import JobRegistry
from crossroads.api.params import BatchId, Page, paging, set_total
from crossroads.api.routes.episodes import episode_public
from crossroads.api.routes.policies import models_dir, policy_ref
from crossroads.api.routes.scenarios import parse_scenario
from crossroads.api.schemas import (
    BatchAccepted,
    BatchCreate,
    BatchProgress,
    BatchPublic,
    BatchSummary,
    EpisodePublic,
)
from crossroads.evaluation.batch import summarize_batch
from crossroads.scenario.network_checks import batch_warnings
from crossroads.scenario.spec import MAX_RUNS
from crossroads.store import Store, crud
from crossroads.store.crud import FINISHED_STATUSES
from crossroads.store.tables import BATCH_STATUSES, EPISODE_OUTCOMES, MAX_ROW_ID, Batch, Episode

router = APIRouter(prefix="/batches", tags=["batches"])

SSE_POLL_S = 0.25  # [s] how often the event stream looks at a running batch
SSE_HEARTBEAT_S = 15.0  # [s] a comment line keeps proxies from closing a quiet stream


def _get(session: Session, batch_id: int) -> Batch:
    batch = crud.get_batch(session=session, batch_id=batch_id)
    if batch is None:
        raise HTTPException(status_code=404, detail=f"no batch {batch_id}")
    return batch


ENDED = (*FINISHED_STATUSES, "interrupted")  # no runner goes on with these by itself


def _aware(moment: datetime | None) -> datetime | None:
    """A stored time as UTC (SQLite gives them back without their zone)."""
    return None if moment is None or moment.tzinfo is not None else moment.replace(tzinfo=UTC)


def _timing(session: Session, batch: Batch, done: int) -> dict[str, Any]:
    """Elapsed time, rate and ETA of a batch, from the store alone (so they survive a reload and a
    restart): the runs recorded since it last started, over the time since then."""
    started = _aware(batch.started_at)
    if started is None or batch.status == "queued":
        return {}
    if batch.status == "running":
        end = datetime.now(UTC)
    elif batch.status == "interrupted":
        end = _aware(batch.heartbeat_at) or _aware(batch.finished_at)
    else:
        end = _aware(batch.finished_at)
    if end is None:
        return {}
    elapsed = max(0.0, (end - started).total_seconds())
    since = session.scalar(select(func.count(Episode.id)).where(
        Episode.batch_id == batch.id, Episode.created_at >= batch.started_at)) or 0
    rate = since / elapsed * 60.0 if since and elapsed > 0 else None
    eta = None
    if batch.status == "running" and rate:
        eta = round(max(0, batch.runs - done) / rate * 60.0)
    return {"elapsed_s": float(round(elapsed)), "since_start": since,
            "rate_per_min": None if rate is None else round(rate, 2),
            "eta_s": None if eta is None else float(eta)}


def _progress(session: Session, batch: Batch, recorded: int, passed: int, errors: int,
              jobs: JobRegistry) -> BatchProgress:
    live = jobs.live_progress(batch.id)
    if live is not None and live.total:
        recorded, passed, errors = live.done, live.passed, live.errors
    total = batch.runs
    return BatchProgress(done=recorded, total=total, passed=passed, errors=errors,
                         fraction=recorded / total if total else 1.0, **_timing(session, batch, recorded))


def _public(session: Session, batch: Batch, jobs: JobRegistry, summary: BatchSummary | None = None) -> BatchPublic:
    counts = crud.outcome_counts(session=session, batch_id=batch.id)
    progress = _progress(session, batch, sum(counts.values()), counts.get("passed", 0), counts.get("error", 0), jobs)
    return BatchPublic(
        id=batch.id, scenario_id=batch.scenario_id, scenario=batch.scenario.name, policy=batch.policy.name,
        status=batch.status, runs=batch.runs, traces=batch.traces, workers=batch.workers,
        executor=batch.executor, error=batch.error, created_at=batch.created_at,
        started_at=batch.started_at, finished_at=batch.finished_at, progress=progress,
        queue_position=jobs.queue_position(batch.id), warnings=list(batch.warnings or []),
        cancel_requested=batch.cancel_requested_at is not None, summary=summary)


def _summary(store: Store, batch_id: int) -> BatchSummary:
    data = summarize_batch(store, batch_id).to_json()
    return BatchSummary.model_validate({k: data[k] for k in BatchSummary.model_fields})


@router.post("", status_code=status.HTTP_202_ACCEPTED)
def start_batch(body: BatchCreate, session: SessionDep, store: StoreDep, jobs: JobsDep,
                settings: SettingsDep, options: OptionsDep) -> BatchAccepted:
    """Store a batch and start it in the background; answers at once with its id (202). Beyond
    the setting max_concurrent_batches running at once, it waits in a queue (status ``queued``,
    ``queue_position`` in GET /batches/{id}) and starts when a running batch ends.
    Follow it with GET /batches/{id} or the event stream GET /batches/{id}/events."""
    if (body.scenario_id is None) == (body.scenario is None):
        raise unprocessable([("scenario_id", "give exactly one of scenario_id (a stored scenario) "
                                             "and scenario (one given inline)")])
    if body.workers is not None and body.workers > settings.max_batch_workers:
        raise unprocessable([("workers", f"at most {settings.max_batch_workers} on this server "
                                         "(setting max_batch_workers)")])
    ref = policy_ref(body.policy, models_dir(options.models_dir), data_dir=settings.data_dir)
    if body.scenario is not None:
        spec = parse_scenario(body.scenario, settings, prefix=("body", "scenario"))
        scenario = crud.get_or_create_scenario(session=session, spec=spec)
    else:
        scenario = crud.get_scenario(session=session, scenario_id=body.scenario_id)
        if scenario is None:
            raise unprocessable([("scenario_id", f"no scenario {body.scenario_id}")])
        spec = parse_scenario(scenario.spec, settings, prefix=("body", "scenario_id"))
    warnings = batch_warnings(spec, settings.data_dir)  # the network as it is now, kept with the batch
    policy = crud.get_or_create_policy(session=session, ref=ref)
    batch = crud.create_batch(session=session, scenario=scenario, policy=policy,
                              runs=body.runs or spec.runs, traces=body.traces,
                              base_dir=settings.data_dir, workers=body.workers, warnings=warnings)
    jobs.submit(batch.id, workers=body.workers)
    return BatchAccepted(id=batch.id, status=batch.status, url=f"/api/batches/{batch.id}",
                         events=f"/api/batches/{batch.id}/events",
                         queue_position=jobs.queue_position(batch.id), warnings=warnings)


@router.get("")
def list_batches(
    session: SessionDep, jobs: JobsDep, response: Response,
    page: Annotated[Page, Depends(paging(100, 1000))],
    status_: Annotated[list[str] | None, Query(alias="status", max_length=len(BATCH_STATUSES),
                                               description="only these statuses")] = None,
    scenario_id: Annotated[int | None, Query(ge=1, le=MAX_ROW_ID)] = None,
) -> list[BatchPublic]:
    """Batches, newest first (progress, no summary); ``X-Total-Count`` says how many match."""
    for s in status_ or []:
        if s not in BATCH_STATUSES:
            raise unprocessable([("status", f"unknown status {s[:40]!r}; one of {', '.join(BATCH_STATUSES)}")],
                                prefix=("query",))
    rows = crud.list_batches(session=session, status=status_, scenario_id=scenario_id,
                             limit=page.limit, offset=page.offset)
    set_total(response, crud.count_batches(session=session, status=status_, scenario_id=scenario_id))
    return [_public(session, b, jobs) for b in rows]


@router.get("/{batch_id}")
def get_batch(batch_id: BatchId, session: SessionDep, store: StoreDep, jobs: JobsDep) -> BatchPublic:
    """A batch: status, progress and the summary of what is recorded so far."""
    batch = _get(session, batch_id)
    return _public(session, batch, jobs, _summary(store, batch_id))


@router.post("/{batch_id}/cancel", status_code=status.HTTP_202_ACCEPTED)
def cancel_batch(batch_id: BatchId, session: SessionDep, jobs: JobsDep) -> dict[str, Any]:
    """Stop a batch: a running (or starting) one soon (``cancelling``: runs in flight are
    dropped), a queued one at once (``cancelled``). The request is stored first, so the batch
    is never resumed, even when the server stops before the batch has. 409 when it has ended
    already."""
    batch = _get(session, batch_id)
    if batch.status in FINISHED_STATUSES:
        raise HTTPException(status_code=409, detail=f"batch {batch_id} is {batch.status} already")
    crud.request_cancel(session=session, batch_id=batch_id)
    if jobs.cancel(batch_id) == "cancelling":
        return {"id": batch_id, "status": "cancelling"}
    # Waiting in the queue, or no runner in this process (a previous server's batch): record it.
    session.refresh(batch)
    if batch.status in FINISHED_STATUSES:  # its runner ended meanwhile
        raise HTTPException(status_code=409, detail=f"batch {batch_id} is {batch.status} already")
    crud.set_batch_status(session=session, batch_id=batch_id, status="cancelled")
    return {"id": batch_id, "status": "cancelled"}


@router.post("/{batch_id}/resume", status_code=status.HTTP_202_ACCEPTED)
def resume_batch(batch_id: BatchId, session: SessionDep, jobs: JobsDep) -> BatchAccepted:
    """Go on with an ``interrupted`` batch (the server stopped while it ran or waited): it is
    queued again and runs what is left; the runs already recorded are kept, never run again.
    409 for a batch in any other state."""
    batch = _get(session, batch_id)
    if batch.status != "interrupted":
        raise HTTPException(status_code=409, detail=f"batch {batch_id} is {batch.status}: only an "
                                                    "interrupted batch can be resumed")
    jobs.resume(batch_id, workers=batch.workers)
    session.refresh(batch)
    return BatchAccepted(id=batch_id, status=batch.status, url=f"/api/batches/{batch_id}",
                         events=f"/api/batches/{batch_id}/events",
                         queue_position=jobs.queue_position(batch_id), warnings=list(batch.warnings or []))


def _sse(event: str, data: dict[str, Any]) -> str:
    return f"event: {event}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n"


def _snapshot(store: Store, batch_id: int, jobs: JobRegistry) -> tuple[dict[str, Any], bool]:
    """The progress event of a batch and whether it has ended (store read in a worker thread)."""
    with store.session() as session:
        batch = _get(session, batch_id)
        public = _public(session, batch, jobs)
        ended = batch.status in ENDED and jobs.live_progress(batch_id) is None
    return {"id": batch_id, "status": public.status, "queue_position": public.queue_position,
            "warnings": public.warnings, **public.progress.model_dump()}, ended


@router.get("/{batch_id}/events", response_class=StreamingResponse,
            responses={200: {"content": {"text/event-stream": {}},
                             "description": "`progress` events, then one `end` event with the summary"}})
async def batch_events(batch_id: BatchId, request: Request, store: StoreDep, jobs: JobsDep) -> StreamingResponse:
    """Server-Sent Events: a ``progress`` event whenever the batch moves (its elapsed time, rate
    and ETA too, to the second), then ``end`` (its status, warnings and summary) when it has
    finished or was interrupted; the stream then closes. Both carry the
    batch's stored ``warnings``, so a client that only follows the stream still sees them."""
    first = await asyncio.to_thread(_snapshot, store, batch_id, jobs)  # a 404 comes before the stream

    async def stream() -> AsyncIterator[str]:
        last: dict[str, Any] | None = None
        quiet_s = 0.0
        current = first
        while True:
            data, ended = current
            if data != last:
                yield _sse("progress", data)
                last, quiet_s = data, 0.0
            if ended:
                summary = await asyncio.to_thread(_summary, store, batch_id)
                yield _sse("end", {"id": batch_id, "status": data["status"], "warnings": data["warnings"],
                                   "summary": summary.model_dump()})
                return
            if await request.is_disconnected():
                return
            await asyncio.sleep(SSE_POLL_S)
            quiet_s += SSE_POLL_S
            if quiet_s >= SSE_HEARTBEAT_S:
                yield ": keep-alive\n\n"
                quiet_s = 0.0
            current = await asyncio.to_thread(_snapshot, store, batch_id, jobs)

    return StreamingResponse(stream(), media_type="text/event-stream",
                             headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})


@router.get("/{batch_id}/episodes")
def batch_episodes(batch_id: BatchId, session: SessionDep, response: Response,
                   page: Annotated[Page, Depends(paging(MAX_RUNS, MAX_RUNS))],
                   outcome: Annotated[list[str] | None, Query(max_length=len(EPISODE_OUTCOMES),
                                                              description="only these outcomes")] = None,
                   ) -> list[EpisodePublic]:
    """The recorded episodes of a batch, in run order (a page of them: by default every one);
    ``X-Total-Count`` says how many match."""
    for o in outcome or []:
        if o not in EPISODE_OUTCOMES:
            raise unprocessable([("outcome", f"unknown outcome {o[:40]!r}; one of {', '.join(EPISODE_OUTCOMES)}")],
                                prefix=("query",))
    _get(session, batch_id)
    rows = crud.batch_results(session=session, batch_id=batch_id, outcomes=outcome,
                              limit=page.limit, offset=page.offset)
    set_total(response, crud.count_results(session=session, batch_id=batch_id, outcomes=outcome))
    return [episode_public(e) for e in rows]
