"""Stored batches as the rows of a report (evaluation/report.py draws them): the store read for a report."""

from __future__ import annotations

from collections.abc import Sequence

from crossroads.evaluation.report import BatchRow
from crossroads.store import crud
from crossroads.store.db import Store


class UnknownBatchError(LookupError):
    """A batch id that is not in the store."""


def report_rows(store: Store, batch_ids: Sequence[int]) -> list[BatchRow]:
    """One report row per batch: its scenario, policy, summary, failed episodes, traces and the
    warnings stored with it."""
    rows = []
    with store.session() as session:
        for batch_id in batch_ids:
            batch = crud.get_batch(session=session, batch_id=batch_id)
            if batch is None:
                raise UnknownBatchError(f"no batch {batch_id} in the store")
            episodes = crud.batch_results(session=session, batch_id=batch_id)
            results = [{
                "id": e.run_index,
                "seed": e.seed,
                "outcome": e.outcome,
                "travel_time_s": e.travel_time_s,
                "detail": e.detail,
                "error": e.error_message if e.outcome == "error" else None,
                "trace_path": e.trace.path if e.trace is not None else None,
            } for e in episodes]
            rows.append(BatchRow.from_results(batch.scenario.name, batch.policy.name, str(batch_id),
                                              results, warnings=batch.warnings or ()))
    return rows
