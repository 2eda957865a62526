"""A search in the results store: keyword-only helpers on a session, as :mod:`crossroads.store.crud`.

Each helper that writes commits its own transaction, so a search interrupted anywhere leaves
every finished trial recorded and nothing half-written.
"""

from __future__ import annotations

from collections.abc import Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, joinedload

from crossroads.store import crud
from crossroads.store.search_tables import SAMPLERS, SEARCH_STATUSES, Search, SearchFailure, SearchTrial

# What a trial keeps of its episode's result (the events stay with the batch's episode row).
RESULT_KEYS = ("outcome", "steps", "time_s", "travel_time_s", "min_distance_m", "min_gap_m",
               "min_ttc_s", "red_stop_margin_m", "detail", "collided_with")


def create_search(*, session: Session, name: str, policy: str, space: Mapping[str, Any],
                  sampler: str, seed: int, budget: int, generation: int, shrink_steps: int,
                  failures_dir: str | Path | None = None) -> Search:
    """A queued search (its policy registered by identity, as a batch's)."""
    if sampler not in SAMPLERS:
        raise ValueError(f"sampler must be one of {', '.join(SAMPLERS)}, got {sampler!r}")
    pol = crud.get_or_create_policy(session=session, ref=policy)
    search = Search(name=name, policy_id=pol.id, space=dict(space), sampler=sampler, seed=int(seed),
                    budget=budget, generation=generation, shrink_steps=shrink_steps,
                    status="queued",
                    failures_dir=None if failures_dir is None else str(Path(failures_dir).resolve()))
    session.add(search)
    session.commit()
    return search


def get_search(*, session: Session, search_id: int) -> Search | None:
    if not crud.in_id_range(search_id):
        return None
    return session.scalar(select(Search).where(Search.id == search_id)
                          .options(joinedload(Search.policy)))


def list_searches(*, session: Session, limit: int = 100, offset: int = 0) -> list[Search]:
    stmt = (select(Search).options(joinedload(Search.policy)).order_by(Search.id.desc())
            .limit(limit).offset(offset))
    return list(session.scalars(stmt))


def set_failures_dir(*, session: Session, search_id: int, path: str | Path) -> None:
    search = session.get(Search, search_id)
    if search is not None:
        search.failures_dir = str(Path(path).resolve())
        session.commit()


def set_search_status(*, session: Session, search_id: int, status: str, error: str | None = None,
                      workers: int | None = None, executor: str | None = None) -> None:
    if status not in SEARCH_STATUSES:
        raise ValueError(f"unknown search status {status!r}")
    search = session.get(Search, search_id)
    if search is None:
        return
    search.status = status
    now = datetime.now(UTC)
    if status == "running":
        search.started_at = search.started_at or now
        search.error = None
        if workers is not None:
            search.workers = workers
        if executor is not None:
            search.executor = executor
    elif status in ("done", "cancelled", "failed"):
        search.finished_at = now
        search.error = error
    session.commit()


def trials(*, session: Session, search_id: int, kind: str | None = None) -> list[SearchTrial]:
    """The search's trials by number (started ones included: ``outcome`` None)."""
    stmt = select(SearchTrial).where(SearchTrial.search_id == search_id)
    if kind is not None:
        stmt = stmt.where(SearchTrial.kind == kind)
    return list(session.scalars(stmt.order_by(SearchTrial.number)))


def start_trial(*, session: Session, search_id: int, number: int, kind: str, parent: int | None,
                params: Mapping[str, Any], seed: int, batch_id: int) -> SearchTrial:
    """The trial's row before its episode runs (its batch given); an existing row gets the batch."""
    row = session.scalar(select(SearchTrial).where(SearchTrial.search_id == search_id,
                                                   SearchTrial.number == number))
    if row is None:
        row = SearchTrial(search_id=search_id, number=number, kind=kind, parent=parent,
                          params=dict(params), seed=int(seed), batch_id=batch_id)
        session.add(row)
    else:
        row.batch_id = batch_id
    try:
        session.commit()
    except IntegrityError:  # a concurrent runner got there first
        session.rollback()
        raise
    return row


def finish_trial(*, session: Session, search_id: int, number: int, outcome: str,
                 objective: float | None, result: Mapping[str, Any] | None) -> None:
    row = session.scalar(select(SearchTrial).where(SearchTrial.search_id == search_id,
                                                   SearchTrial.number == number))
    if row is None:
        raise ValueError(f"search {search_id} has no trial {number}")
    row.outcome = outcome
    row.objective = objective
    row.result = None if result is None else {k: result.get(k) for k in RESULT_KEYS if k in result}
    session.commit()


def record_failure(*, session: Session, search_id: int, trial_number: int, minimal_number: int,
                   outcome: str, params: Mapping[str, Any], seed: int, spec: Mapping[str, Any],
                   content_hash: str, distance: float, off_nominal: list[str],
                   yaml_path: str | None) -> SearchFailure:
    """A shrunk failure (idempotent: an existing row for the trial is returned as it is)."""
    row = session.scalar(select(SearchFailure).where(SearchFailure.search_id == search_id,
                                                     SearchFailure.trial_number == trial_number))
    if row is not None:
        return row
    row = SearchFailure(search_id=search_id, trial_number=trial_number,
                        minimal_number=minimal_number, outcome=outcome, params=dict(params),
                        seed=int(seed), spec=dict(spec), content_hash=content_hash,
                        distance=distance, off_nominal=list(off_nominal), yaml_path=yaml_path)
    session.add(row)
    session.commit()
    return row


def failures(*, session: Session, search_id: int) -> list[SearchFailure]:
    stmt = (select(SearchFailure).where(SearchFailure.search_id == search_id)
            .order_by(SearchFailure.trial_number))
    return list(session.scalars(stmt))


def get_failure(*, session: Session, search_id: int, failure_id: int) -> SearchFailure | None:
    if not crud.in_id_range(failure_id):
        return None
    row = session.get(SearchFailure, failure_id)
    return row if row is not None and row.search_id == search_id else None
