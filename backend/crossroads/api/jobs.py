"""The batch jobs of the running API: each batch runs outside the request path.

A job is one :class:`~crossroads.evaluation.batch.BatchRunner` driven from a background thread
of this process; the runner's executor runs the episodes in worker processes (or on Ray), so
neither a request nor the event loop ever waits on a simulation. The registry knows the live
jobs (progress, cancel); once a job ends, the store is the truth about its batch.

A batch that cannot even start (its network does not build, its policy does not load) is marked
``failed`` with the reason, so no batch is left ``queued`` forever by this process.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from pathlib import Path

from crossroads.evaluation.batch import BatchRunner, Progress, make_executor
from crossroads.store import Store, crud
from crossroads.store.crud import FINISHED_STATUSES

log = logging.getLogger(__name__)


@dataclass
class Job:
    batch_id: int
    runner: BatchRunner
    thread: threading.Thread
    error: str | None = None

    @property
    def alive(self) -> bool:
        return self.thread.is_alive()


class JobRegistry:
    """The batches this API process runs: submit, progress, cancel, shutdown."""

    def __init__(self, store: Store, *, data_dir: str | Path, ray_address: str | None = None) -> None:
        self.store = store
        self.data_dir = Path(data_dir)
        self.ray_address = ray_address
        self._jobs: dict[int, Job] = {}
        self._lock = threading.Lock()

    def submit(self, batch_id: int, *, workers: int | None = None) -> Job:
        """Start running the stored batch ``batch_id`` in the background; returns at once."""
        with self._lock:
            current = self._jobs.get(batch_id)
            if current is not None and current.alive:
                return current
            executor = make_executor(workers=workers, ray_address=self.ray_address)
            runner = BatchRunner(self.store, batch_id, data_dir=self.data_dir, executor=executor)
            thread = threading.Thread(target=self._run, args=(batch_id, runner), daemon=True,
                                      name=f"crossroads-api-batch-{batch_id}")
            job = Job(batch_id, runner, thread)
            self._jobs[batch_id] = job
            thread.start()
            return job

    def _run(self, batch_id: int, runner: BatchRunner) -> None:
        try:
            runner.run()
        except BaseException as exc:  # noqa: BLE001 - a job's end is recorded, never raised
            message = f"{type(exc).__name__}: {exc}"
            log.warning("batch %s failed: %s", batch_id, message)
            with self._lock:
                job = self._jobs.get(batch_id)
                if job is not None:
                    job.error = message
            self._mark_failed(batch_id, message)

    def _mark_failed(self, batch_id: int, message: str) -> None:
        """A runner that failed before it could set the batch's status (e.g. in its plan)."""
        try:
            with self.store.session() as session:
                batch = crud.get_batch(session=session, batch_id=batch_id)
                if batch is not None and batch.status not in FINISHED_STATUSES:
                    crud.set_batch_status(session=session, batch_id=batch_id, status="failed",
                                          error=message)
        except Exception:  # noqa: BLE001 - the store itself is gone (shutdown)
            log.exception("cannot mark batch %s failed", batch_id)

    def get(self, batch_id: int) -> Job | None:
        with self._lock:
            return self._jobs.get(batch_id)

    def live_progress(self, batch_id: int) -> Progress | None:
        """The runner's progress while its job runs; ``None`` once it ended (ask the store)."""
        job = self.get(batch_id)
        if job is None or not job.alive:
            return None
        return job.runner.progress

    def running(self) -> list[int]:
        with self._lock:
            return [b for b, j in self._jobs.items() if j.alive]

    def cancel(self, batch_id: int) -> bool:
        """Ask a live job to stop (runs in flight are dropped; the batch ends ``cancelled``).
        False when this process runs no such job."""
        job = self.get(batch_id)
        if job is None or not job.alive:
            return False
        job.runner.cancel()
        return True

    def shutdown(self, timeout_s: float = 10.0) -> None:
        """Cancel every live job and wait (bounded) for their threads."""
        with self._lock:
            jobs = list(self._jobs.values())
        for job in jobs:
            job.runner.cancel()
        for job in jobs:
            job.thread.join(timeout_s)
