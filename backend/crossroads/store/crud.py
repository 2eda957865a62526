"""Keyword-only helpers over the store's tables; the caller injects the session.

Helpers that create or change rows commit (one helper call = one transaction), so a result
written by :func:`record_episode` is either wholly in the store or not at all.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, joinedload

from crossroads.policy.identity import policy_identity
from crossroads.store.tables import (
    BATCH_STATUSES,
    EPISODE_OUTCOMES,
    MAX_ROW_ID,
    TRACE_MODES,
    Batch,
    Episode,
    Policy,
    Scenario,
    Trace,
    utcnow,
)

FINISHED_STATUSES = ("done", "cancelled", "failed")
# queued, running, interrupted (a server stopped under it): what a restarted service may resume
UNFINISHED_STATUSES = tuple(s for s in BATCH_STATUSES if s not in FINISHED_STATUSES)


def in_id_range(value: int | None, *, low: int = 1) -> bool:
    """Whether ``value`` fits the store's INTEGER id columns (a larger one would make the database
    driver fail instead of finding nothing)."""
    return value is not None and low <= value <= MAX_ROW_ID


def _get_or_create(session: Session, model: type[Any], unique: Mapping[str, Any],
                   values: Mapping[str, Any]) -> Any:
    """Select by the unique columns, else insert (a concurrent insert of the same row is caught)."""
    stmt = select(model).filter_by(**unique)
    row = session.scalars(stmt).first()
    if row is not None:
        return row
    try:
        with session.begin_nested():
            row = model(**unique, **values)
            session.add(row)
        session.commit()
        return row
    except IntegrityError:
        session.rollback()
        row = session.scalars(stmt).first()
        if row is None:
            raise
        return row


# --- scenarios and policies ---------------------------------------------------------------------


def get_or_create_scenario(*, session: Session, spec: Any) -> Scenario:
    """The row of a :class:`~crossroads.scenario.spec.ScenarioSpec` (by content hash)."""
    from crossroads.scenario.spec import canonical_json, content_hash

    return _get_or_create(session, Scenario, {"content_hash": content_hash(spec)},
                          {"name": spec.name, "spec": json.loads(canonical_json(spec))})


def get_scenario(*, session: Session, scenario_id: int) -> Scenario | None:
    return session.get(Scenario, scenario_id) if in_id_range(scenario_id) else None


def list_scenarios(*, session: Session, limit: int = 100, offset: int = 0) -> list[Scenario]:
    """Scenarios, oldest first."""
    return list(session.scalars(select(Scenario).order_by(Scenario.id).limit(limit).offset(offset)))


def count_scenarios(*, session: Session) -> int:
    return int(session.scalar(select(func.count()).select_from(Scenario)) or 0)


def batch_counts(*, session: Session, scenario_ids: Iterable[int]) -> dict[int, int]:
    """How many batches ran each of ``scenario_ids`` (absent: none)."""
    ids = list(scenario_ids)
    if not ids:
        return {}
    stmt = (select(Batch.scenario_id, func.count()).where(Batch.scenario_id.in_(ids))
            .group_by(Batch.scenario_id))
    return {int(sid): int(n) for sid, n in session.execute(stmt)}


def scenario_spec(*, scenario: Scenario) -> Any:
    """The stored spec, validated again into a ScenarioSpec (references are not checked)."""
    from crossroads.scenario.spec import validate_scenario

    return validate_scenario(scenario.spec, source=f"stored scenario {scenario.id}",
                             check_references=False)


def get_or_create_policy(*, session: Session, ref: str, card: Mapping[str, Any] | None = None) -> Policy:
    """The row of a policy reference (``rule`` or a checkpoint path), by its identity hash."""
    ident = policy_identity(ref)
    return _get_or_create(
        session, Policy, {"file_hash": ident.file_hash},
        {"name": ident.name, "ref": ident.ref, "kind": ident.kind,
         "card": dict(card) if card is not None else ident.card})


def get_policy(*, session: Session, policy_id: int) -> Policy | None:
    return session.get(Policy, policy_id) if in_id_range(policy_id) else None


# --- batches ------------------------------------------------------------------------------------


def create_batch(*, session: Session, scenario: Scenario, policy: Policy, runs: int,
                 base_seed: int | None = None, traces: str = "failed", base_dir: str | Path | None = None,
                 workers: int | None = None, executor: str | None = None,
                 warnings: Sequence[str] = ()) -> Batch:
    """A queued batch of ``runs`` runs (base seed: the scenario's own ``seed``), with the
    ``warnings`` its network gave now (stored as NULL when there are none). At most ``MAX_RUNS``
    runs: the runner derives every seed before the first episode, so a batch beyond that would
    spend its start-up building seeds."""
    from crossroads.scenario.spec import MAX_RUNS

    if not 1 <= runs <= MAX_RUNS:
        raise ValueError(f"runs must be in 1..{MAX_RUNS}, got {runs}")
    if traces not in TRACE_MODES:
        raise ValueError(f"traces must be one of {', '.join(TRACE_MODES)}, got {traces!r}")
    if isinstance(warnings, str):  # a str is a Sequence too: it would be stored letter by letter
        raise TypeError("warnings must be a sequence of strings, not one string")
    batch = Batch(scenario_id=scenario.id, policy_id=policy.id, runs=runs,
                  base_seed=int(scenario.spec["seed"] if base_seed is None else base_seed),
                  status="queued", traces=traces,
                  base_dir=None if base_dir is None else str(Path(base_dir).resolve()),
                  workers=workers, executor=executor, warnings=[str(w) for w in warnings] or None)
    session.add(batch)
    session.commit()
    return batch


def get_batch(*, session: Session, batch_id: int) -> Batch | None:
    if not in_id_range(batch_id):
        return None
    stmt = (select(Batch).where(Batch.id == batch_id)
            .options(joinedload(Batch.scenario), joinedload(Batch.policy)))
    return session.scalars(stmt).first()


def list_batches(*, session: Session, status: str | Sequence[str] | None = None,
                 scenario_id: int | None = None, policy_id: int | None = None,
                 limit: int = 100, offset: int = 0) -> list[Batch]:
    """Batches, newest first."""
    stmt = _batch_filter(select(Batch).options(joinedload(Batch.scenario), joinedload(Batch.policy)),
                         status, scenario_id, policy_id)
    stmt = stmt.order_by(Batch.id.desc()).limit(limit).offset(offset)
    return list(session.scalars(stmt).unique())


def count_batches(*, session: Session, status: str | Sequence[str] | None = None,
                  scenario_id: int | None = None, policy_id: int | None = None) -> int:
    """How many batches :func:`list_batches` would page through."""
    stmt = _batch_filter(select(func.count()).select_from(Batch), status, scenario_id, policy_id)
    return int(session.scalar(stmt) or 0)


def _batch_filter(stmt: Any, status: str | Sequence[str] | None, scenario_id: int | None,
                  policy_id: int | None) -> Any:
    if status is not None:
        stmt = stmt.where(Batch.status.in_([status] if isinstance(status, str) else list(status)))
    for column, value in ((Batch.scenario_id, scenario_id), (Batch.policy_id, policy_id)):
        if value is not None:  # an id beyond the column matches nothing (and never reaches the driver)
            stmt = stmt.where(column == value) if in_id_range(value) else stmt.where(False)
    return stmt


def unfinished_batches(*, session: Session) -> list[Batch]:
    """Every batch still queued or running and not asked to cancel, oldest first (what a
    restarted service resumes)."""
    stmt = (select(Batch).where(Batch.status.in_(UNFINISHED_STATUSES), Batch.cancel_requested_at.is_(None))
            .order_by(Batch.id))
    return list(session.scalars(stmt))


def request_cancel(*, session: Session, batch_id: int) -> Batch | None:
    """Record that a user asked to cancel the batch (the first time counts); committed at once,
    so a restart never resumes it, whatever its runner got to record. None: no such batch."""
    batch = session.get(Batch, batch_id) if in_id_range(batch_id) else None
    if batch is None:
        return None
    if batch.cancel_requested_at is None:
        batch.cancel_requested_at = utcnow()
        session.commit()
    return batch


def end_requested_cancels(*, session: Session) -> list[int]:
    """Mark ``cancelled`` every unfinished batch a user asked to cancel (its runner stopped before
    it could record that, e.g. the process was killed); their ids."""
    rows = list(session.scalars(select(Batch).where(Batch.status.in_(UNFINISHED_STATUSES),
                                                    Batch.cancel_requested_at.is_not(None))))
    for batch in rows:
        batch.status = "cancelled"
        batch.finished_at = utcnow()
    session.commit()
    return [b.id for b in rows]


def set_batch_status(*, session: Session, batch_id: int, status: str, error: str | None = None,
                     workers: int | None = None, executor: str | None = None) -> Batch:
    """Move a batch to ``status``: ``running`` stamps started_at (and clears finished_at, error);
    a finished status stamps finished_at."""
    if status not in BATCH_STATUSES:
        raise ValueError(f"status must be one of {', '.join(BATCH_STATUSES)}, got {status!r}")
    batch = session.get(Batch, batch_id)
    if batch is None:
        raise LookupError(f"no batch {batch_id}")
    batch.status = status
    if status == "running":
        batch.started_at = utcnow()
        batch.finished_at = None
        batch.error = None
    if status in FINISHED_STATUSES:
        batch.finished_at = utcnow()
    if error is not None:
        batch.error = error
    if workers is not None:
        batch.workers = workers
    if executor is not None:
        batch.executor = executor
    session.commit()
    return batch


def delete_batch(*, session: Session, batch_id: int) -> bool:
    """Delete a batch with its episodes (their traces' rows stay; files are the caller's)."""
    batch = session.get(Batch, batch_id) if in_id_range(batch_id) else None
    if batch is None:
        return False
    session.execute(Episode.__table__.delete().where(Episode.batch_id == batch_id))
    session.delete(batch)
    session.commit()
    return True


# --- episodes -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class TraceRef:
    """Where an episode's trace lies: a file (``path``) or its bytes (``blob``)."""

    size_bytes: int
    sha256: str
    path: str | None = None
    blob: bytes | None = None


def _finite(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


def record_episode(*, session: Session, batch_id: int, run_index: int, seed: int,
                   result: Any | None = None, error: str | None = None,
                   trace: TraceRef | None = None, wall_s: float | None = None) -> Episode | None:
    """Record run ``run_index`` of a batch in one transaction (with its trace row, if any).

    Give either ``result`` (an :class:`~crossroads.evaluation.episode.EpisodeResult` or its JSON
    dict) or ``error`` (the message; outcome ``error``). Idempotent: when the run is already
    recorded nothing changes and ``None`` is returned, so a run is never counted twice.
    """
    if (result is None) == (error is None):
        raise ValueError("give exactly one of result and error")
    if session.scalar(select(Episode.id).where(Episode.batch_id == batch_id,
                                               Episode.run_index == run_index)) is not None:
        return None
    if error is not None:
        fields: dict[str, Any] = {"outcome": "error", "error_message": error, "detail": "",
                                  "events": []}
    else:
        data = result if isinstance(result, Mapping) else result.to_json()
        if data["outcome"] not in EPISODE_OUTCOMES:
            raise ValueError(f"unknown outcome {data['outcome']!r}")
        fields = {
            "outcome": data["outcome"], "travel_time_s": _finite(data.get("travel_time_s")),
            "steps": data.get("steps"), "time_s": _finite(data.get("time_s")),
            "min_distance_m": _finite(data.get("min_distance_m")), "min_gap_m": _finite(data.get("min_gap_m")),
            "detail": data.get("detail") or "", "collided_with": data.get("collided_with"),
            "events": list(data.get("events") or []),
        }
    try:
        trace_row = None
        if trace is not None:
            trace_row = Trace(path=trace.path, blob=trace.blob, size_bytes=trace.size_bytes,
                              sha256=trace.sha256)
            session.add(trace_row)
            session.flush()
        episode = Episode(batch_id=batch_id, run_index=run_index, seed=int(seed), wall_s=wall_s,
                          trace_id=None if trace_row is None else trace_row.id, **fields)
        session.add(episode)
        session.commit()
    except IntegrityError:
        session.rollback()
        already = session.scalar(select(Episode.id).where(Episode.batch_id == batch_id,
                                                          Episode.run_index == run_index))
        if already is not None:  # a concurrent writer recorded it first
            return None
        raise
    return episode


def done_run_indices(*, session: Session, batch_id: int) -> set[int]:
    """The run indices of a batch already recorded (errors included)."""
    return set(session.scalars(select(Episode.run_index).where(Episode.batch_id == batch_id)))


def batch_results(*, session: Session, batch_id: int, outcomes: Iterable[str] | None = None,
                  limit: int | None = None, offset: int = 0) -> list[Episode]:
    """A batch's episodes in run order (optionally only some outcomes, a page of ``limit`` from
    ``offset``), traces loaded."""
    if not in_id_range(batch_id):
        return []
    stmt = (select(Episode).where(Episode.batch_id == batch_id)
            .options(joinedload(Episode.trace)).order_by(Episode.run_index))
    if outcomes is not None:
        stmt = stmt.where(Episode.outcome.in_(list(outcomes)))
    if limit is not None or offset:
        stmt = stmt.limit(limit).offset(offset)
    return list(session.scalars(stmt).unique())


def count_results(*, session: Session, batch_id: int, outcomes: Iterable[str] | None = None) -> int:
    """How many episodes :func:`batch_results` would page through."""
    if not in_id_range(batch_id):
        return 0
    stmt = select(func.count()).select_from(Episode).where(Episode.batch_id == batch_id)
    if outcomes is not None:
        stmt = stmt.where(Episode.outcome.in_(list(outcomes)))
    return int(session.scalar(stmt) or 0)


def outcome_counts(*, session: Session, batch_id: int) -> dict[str, int]:
    stmt = (select(Episode.outcome, func.count()).where(Episode.batch_id == batch_id)
            .group_by(Episode.outcome))
    return {outcome: int(n) for outcome, n in session.execute(stmt)}


def get_episode(*, session: Session, batch_id: int, run_index: int) -> Episode | None:
    if not (in_id_range(batch_id) and in_id_range(run_index, low=0)):
        return None
    stmt = (select(Episode).where(Episode.batch_id == batch_id, Episode.run_index == run_index)
            .options(joinedload(Episode.trace)))
    return session.scalars(stmt).first()


def paired_results(*, session: Session, batch_a: int, batch_b: int) -> list[tuple[Episode, Episode]]:
    """Episodes of two batches that met the same seed, paired in run order (for McNemar)."""
    a = {e.seed: e for e in batch_results(session=session, batch_id=batch_a)}
    return [(a[e.seed], e) for e in batch_results(session=session, batch_id=batch_b) if e.seed in a]
