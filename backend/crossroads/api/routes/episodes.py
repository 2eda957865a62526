"""Episodes: one run's result, and its trace (the per-step frames) for playback."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Query

from crossroads.api.deps import SessionDep
from crossroads.api.params import BatchId, RunIndex
from crossroads.api.schemas import EpisodePublic
from crossroads.evaluation.trace import Trace
from crossroads.store import crud
from crossroads.store.tables import Episode, Trace as TraceRow

router = APIRouter(prefix="/episodes", tags=["episodes"])


def episode_public(e: Episode) -> EpisodePublic:
    return EpisodePublic(
        batch_id=e.batch_id, run_index=e.run_index, seed=e.seed, outcome=e.outcome, passed=e.passed,
        travel_time_s=e.travel_time_s, steps=e.steps, time_s=e.time_s, min_distance_m=e.min_distance_m,
        min_gap_m=e.min_gap_m,
        detail=e.detail, collided_with=e.collided_with, events=list(e.events or []),
        error_message=e.error_message, wall_s=e.wall_s, has_trace=e.trace_id is not None)


def _get(session: Any, batch_id: int, run_index: int) -> Episode:
    episode = crud.get_episode(session=session, batch_id=batch_id, run_index=run_index)
    if episode is None:
        raise HTTPException(status_code=404, detail=f"no episode {run_index} in batch {batch_id}")
    return episode


def _load_trace(row: TraceRow) -> Trace:
    if row.path is not None:
        path = Path(row.path)
        if not path.is_file():
            raise HTTPException(status_code=404, detail="the episode's trace file is gone")
        return Trace.load(path)
    with tempfile.NamedTemporaryFile(suffix=".trace.npz") as f:  # a trace kept in the database
        f.write(row.blob or b"")
        f.flush()
        return Trace.load(f.name)


@router.get("/{batch_id}/{run_index}")
def get_episode(batch_id: BatchId, run_index: RunIndex, session: SessionDep) -> EpisodePublic:
    """The result of run ``run_index`` of a batch."""
    return episode_public(_get(session, batch_id, run_index))


@router.get("/{batch_id}/{run_index}/trace")
def get_trace(batch_id: BatchId, run_index: RunIndex, session: SessionDep,
              stride: Annotated[int, Query(ge=1, le=10_000, description="every stride-th step (and the last)")] = 1,
              ) -> dict[str, Any]:
    """The episode's trace as ``{header, frames}``; 404 when none was kept (see the batch's
    ``traces`` setting)."""
    episode = _get(session, batch_id, run_index)
    if episode.trace is None:
        raise HTTPException(status_code=404, detail=f"no trace was kept for episode {run_index} "
                            f"of batch {batch_id}")
    return _load_trace(episode.trace).to_json(stride)
