"""The batch jobs of the running API: each batch runs outside the request path.

A job is one :class:`~crossroads.evaluation.batch.BatchRunner` driven from a background thread
of this process; the runner's executor runs the episodes in worker processes (or on Ray), so
neither a request nor the event loop ever waits on a simulation. The registry knows the live
jobs (progress, cancel); once a job ends, the store is the truth about its batch.

At most ``max_running`` batches run at once (each one starts its own worker processes, so an
unbounded number would swamp the machine); a batch started beyond that waits in a FIFO queue,
keeps its stored status ``queued``, and starts when a running one ends.

A batch that cannot even start (its network does not build, its policy does not load) is marked
``failed`` with the reason, so no batch is left ``queued`` forever by this process. On shutdown
the running and the waiting batches are stopped and marked ``interrupted``: the next start goes on
with them (:meth:`JobRegistry.resume_unfinished`, the runner skips every run already recorded), or,
with resuming turned off, shows them interrupted until a user resumes one (:meth:`JobRegistry.resume`).

A process that is killed cannot say so: every few seconds (``heartbeat_s``) the registry stamps
``batches.heartbeat_at`` of its batches, and marks ``interrupted`` any unfinished batch whose stamp
is older than ``stale_after_s`` (its process stopped); so no batch is shown running forever.
Batches without a stamp (run by ``crossroads evaluate``) are never judged so.

A cancel is recorded in the store before anything else (``batches.cancel_requested_at``, written
by the route): a batch asked to cancel never starts, is never put back in the queue and is never
resumed, whichever state the request found it in. Each episode has a wall-clock limit
(``episode_wall_limit_s``): one that runs longer is stopped and recorded as an error.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from datetime import timedelta
from pathlib import Path
from typing import Literal, Protocol

from sqlalchemy import select, update

from crossroads.evaluation.batch import BatchResult, BatchRunner, Progress
from crossroads.evaluation.executors import Executor, ProcessExecutor, RayExecutor
from crossroads.store import Store, crud
from crossroads.store.crud import FINISHED_STATUSES
from crossroads.store.tables import Batch, utcnow

log = logging.getLogger(__name__)

HEARTBEAT_S = 5.0  # [s] how often the registry says its batches are still in hand
STALE_AFTER_S = 30.0  # [s] an unfinished batch not stamped for this long: its process stopped
INTERRUPTED_BY_SHUTDOWN = "interrupted: the server stopped while the batch ran; resume it"
INTERRUPTED_BY_LOSS = "interrupted: the server running it stopped (no sign of it since {when}); resume it"

CancelOutcome = Literal["cancelling", "dequeued"]


class Runner(Protocol):
    """What the registry needs of a batch runner (a :class:`BatchRunner`, or a test's fake)."""

    @property
    def progress(self) -> Progress: ...

    def run(self) -> BatchResult: ...

    def cancel(self) -> None: ...


RunnerFactory = Callable[[int, int | None], Runner]  # (batch id, workers) -> a runner


@dataclass
class Job:
    """One batch of this process: waiting in the queue (no thread yet) or started."""

    batch_id: int
    workers: int | None
    runner: Runner | None = None
    thread: threading.Thread | None = None
    error: str | None = None
    cancel_asked: bool = False  # by a user (a shutdown's stop is not a cancel)

    @property
    def alive(self) -> bool:
        return self.thread is not None and self.thread.is_alive()

    @property
    def waiting(self) -> bool:
        return self.thread is None


class JobRegistry:
    """The batches this API process runs: submit (run or queue), progress, cancel, resume,
    shutdown. Thread-safe; every method returns at once except :meth:`shutdown`."""

    def __init__(self, store: Store, *, data_dir: str | Path, ray_address: str | None = None,
                 max_running: int = 2, runner_factory: RunnerFactory | None = None,
                 episode_wall_limit_s: float | None = None, heartbeat_s: float = HEARTBEAT_S,
                 stale_after_s: float = STALE_AFTER_S) -> None:
        if max_running < 1:
            raise ValueError(f"max_running must be >= 1, got {max_running}")
        if episode_wall_limit_s is not None and not episode_wall_limit_s > 0:
            raise ValueError(f"episode_wall_limit_s must be > 0, got {episode_wall_limit_s}")
        self.store = store
        self.data_dir = Path(data_dir)
        self.ray_address = ray_address
        self.max_running = max_running
        self.episode_wall_limit_s = episode_wall_limit_s
        self._make_runner = runner_factory or self._batch_runner
        self._jobs: dict[int, Job] = {}
        self._active: set[int] = set()  # started and not yet ended (decides when the queue moves)
        self._queue: deque[int] = deque()
        self._closing = False
        self._lock = threading.Lock()
        if not 0 < heartbeat_s < stale_after_s:
            raise ValueError(f"need 0 < heartbeat_s < stale_after_s, got {heartbeat_s} and {stale_after_s}")
        self.heartbeat_s, self.stale_after_s = heartbeat_s, stale_after_s
        self._beats = threading.Event()  # set: the heartbeat thread stops
        self._beat_thread: threading.Thread | None = None

    def _batch_runner(self, batch_id: int, workers: int | None) -> Runner:
        executor: Executor
        if self.ray_address:
            executor = RayExecutor(self.ray_address, workers, wall_limit_s=self.episode_wall_limit_s)
        else:
            executor = ProcessExecutor(workers, wall_limit_s=self.episode_wall_limit_s)
        return BatchRunner(self.store, batch_id, data_dir=self.data_dir, executor=executor)

    # --- submitting ------------------------------------------------------------------------------

    def submit(self, batch_id: int, *, workers: int | None = None) -> Job:
        """Run the stored batch ``batch_id`` in the background, or queue it when
        ``max_running`` batches run already; returns at once."""
        with self._lock:
            current = self._jobs.get(batch_id)
            if current is not None and (current.waiting or batch_id in self._active):
                return current
            job = Job(batch_id, workers)
            self._jobs[batch_id] = job
            if self._closing:
                return job  # stays queued in the store; the next start resumes it
            if len(self._active) < self.max_running:
                self._start(job)
            else:
                self._queue.append(batch_id)
        self._stamp([batch_id])  # in hand from now on (a waiting batch too)
        return job

    def resume(self, batch_id: int, *, workers: int | None = None) -> Job:
        """Go on with an ``interrupted`` batch (a user's Resume): queued again, then run; the
        runs already recorded are skipped. The caller checks the status."""
        with self.store.session() as session:
            session.execute(update(Batch).where(Batch.id == batch_id, Batch.status == "interrupted")
                            .values(status="queued", error=None))
            session.commit()
        return self.submit(batch_id, workers=workers)

    def _start(self, job: Job) -> None:
        """Start ``job``'s thread (the lock is held)."""
        job.runner = self._make_runner(job.batch_id, job.workers)
        job.thread = threading.Thread(target=self._run, args=(job,), daemon=True,
                                      name=f"crossroads-api-batch-{job.batch_id}")
        self._active.add(job.batch_id)
        job.thread.start()

    def _run(self, job: Job) -> None:
        try:
            if self._still_wanted(job.batch_id):
                assert job.runner is not None
                job.runner.run()
        except BaseException as exc:  # noqa: BLE001 - a job's end is recorded, never raised
            message = f"{type(exc).__name__}: {exc}"
            log.warning("batch %s failed: %s", job.batch_id, message)
            job.error = message
            self._mark_failed(job.batch_id, message)
        finally:
            self._ended(job.batch_id)

    def _still_wanted(self, batch_id: int) -> bool:
        """False when the stored batch has ended meanwhile (e.g. cancelled by another process
        while it waited): running it would overwrite that. A batch asked to cancel is marked
        ``cancelled`` here, never started."""
        with self.store.session() as session:
            batch = crud.get_batch(session=session, batch_id=batch_id)
            if batch is None or batch.status in FINISHED_STATUSES:
                return False
            if batch.cancel_requested_at is not None:
                crud.set_batch_status(session=session, batch_id=batch_id, status="cancelled")
                return False
            return True

    def _ended(self, batch_id: int) -> None:
        """A job's thread is about to end: free its slot and start the next queued batches."""
        with self._lock:
            self._active.discard(batch_id)
            while self._queue and not self._closing and len(self._active) < self.max_running:
                self._start(self._jobs[self._queue.popleft()])

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

    def resume_unfinished(self) -> list[int]:
        """Submit every stored batch still ``queued``, ``running`` or ``interrupted`` (left by a
        process that stopped), oldest first; the runner skips the runs already recorded, so none is run or
        counted twice. A batch a user asked to cancel is marked ``cancelled`` instead. Returns the
        ids of the batches submitted."""
        with self.store.session() as session:
            ended = crud.end_requested_cancels(session=session)
            rows = [(b.id, b.workers, b.status) for b in crud.unfinished_batches(session=session)]
        if ended:
            log.info("cancelled %d batch(es) asked to cancel before the restart: %s", len(ended),
                     ", ".join(map(str, ended)))
        for batch_id, workers, status in rows:
            if status == "interrupted":
                self.resume(batch_id, workers=workers)
            else:
                self.submit(batch_id, workers=workers)
        if rows:
            log.info("resuming %d unfinished batch(es): %s", len(rows), ", ".join(str(r[0]) for r in rows))
        return [row[0] for row in rows]

    # --- reading ---------------------------------------------------------------------------------

    def get(self, batch_id: int) -> Job | None:
        with self._lock:
            return self._jobs.get(batch_id)

    def live_progress(self, batch_id: int) -> Progress | None:
        """The runner's progress while its job runs; ``None`` otherwise (ask the store)."""
        job = self.get(batch_id)
        if job is None or job.runner is None or not job.alive:
            return None
        return job.runner.progress

    def running(self) -> list[int]:
        with self._lock:
            return sorted(self._active)

    def queued(self) -> list[int]:
        """The waiting batches, next first."""
        with self._lock:
            return list(self._queue)

    def queue_position(self, batch_id: int) -> int | None:
        """1 for the next batch to start, ...; None when ``batch_id`` does not wait here."""
        with self._lock:
            try:
                return self._queue.index(batch_id) + 1
            except ValueError:
                return None

    # --- stopping --------------------------------------------------------------------------------

    def cancel(self, batch_id: int) -> CancelOutcome | None:
        """Cancel a batch of this process: a running one is asked to stop soon (``"cancelling"``:
        runs in flight are dropped; it ends ``cancelled``), a waiting one leaves the queue at once
        (``"dequeued"``: the caller records ``cancelled``). None: this process has no such job."""
        with self._lock:
            if batch_id in self._queue:
                self._queue.remove(batch_id)
                del self._jobs[batch_id]
                return "dequeued"
            job = self._jobs.get(batch_id)
            if job is None or job.runner is None or batch_id not in self._active:
                return None
            job.cancel_asked = True
            job.runner.cancel()
            return "cancelling"

    def shutdown(self, timeout_s: float = 10.0) -> None:
        """Stop every running job and wait (bounded) for their threads. Batches stopped this
        way, and the waiting ones, are marked ``interrupted`` in the store: the next start
        resumes them (or a user does)."""
        self._beats.set()
        with self._lock:
            self._closing = True
            waiting = list(self._queue)
            self._queue.clear()
            jobs = [self._jobs[b] for b in self._active]
        for job in jobs:
            assert job.runner is not None
            job.runner.cancel()
        for batch_id in waiting:
            self._interrupt(batch_id, ("queued",))
        for job in jobs:
            assert job.thread is not None
            job.thread.join(timeout_s)
            if not job.alive and not job.cancel_asked and job.error is None:
                # the runner recorded ``cancelled`` (a stop that is not a user's cancel)
                self._interrupt(job.batch_id, ("cancelled", "queued", "running"))
        if self._beat_thread is not None:
            self._beat_thread.join(timeout_s)

    def _interrupt(self, batch_id: int, found: tuple[str, ...]) -> None:
        """Mark a batch the shutdown stopped ``interrupted`` (when its status is one of ``found``
        and no user asked to cancel it)."""
        try:
            with self.store.session() as session:
                batch = crud.get_batch(session=session, batch_id=batch_id)
                if batch is not None and batch.status in found and batch.cancel_requested_at is None:
                    batch.status, batch.error, batch.finished_at = "interrupted", INTERRUPTED_BY_SHUTDOWN, None
                    session.commit()
        except Exception:  # noqa: BLE001 - the store went first; the batch stays as it is
            log.exception("cannot mark batch %s interrupted", batch_id)

    # --- the heartbeat -----------------------------------------------------------------------------

    def start_heartbeat(self) -> None:
        """Stamp this registry's batches every ``heartbeat_s`` and mark ``interrupted`` those
        abandoned by a stopped process, in a daemon thread (until :meth:`shutdown`). Marks the
        abandoned ones once at once too."""
        if self._beat_thread is not None:
            return
        self.mark_abandoned()
        self._beat_thread = threading.Thread(target=self._beat_loop, daemon=True, name="crossroads-api-heartbeat")
        self._beat_thread.start()

    def _beat_loop(self) -> None:
        while not self._beats.wait(self.heartbeat_s):
            try:
                self._stamp(self.in_hand())
                self.mark_abandoned()
            except Exception:  # noqa: BLE001 - a store hiccup: the next beat tries again
                log.exception("batch heartbeat failed")

    def in_hand(self) -> list[int]:
        """The batches this registry runs or queues."""
        with self._lock:
            return sorted(self._active | set(self._queue))

    def _stamp(self, batch_ids: list[int]) -> None:
        if not batch_ids:
            return
        with self.store.session() as session:
            session.execute(update(Batch).where(Batch.id.in_(batch_ids), Batch.status.in_(("queued", "running")))
                            .values(heartbeat_at=utcnow()))
            session.commit()

    def mark_abandoned(self) -> list[int]:
        """Mark ``interrupted`` every batch still ``queued`` or ``running`` whose heartbeat is
        older than ``stale_after_s`` and that this registry does not hold (its process stopped
        without saying so, e.g. killed); their ids. A batch asked to cancel is left to
        :meth:`resume_unfinished` (it ends ``cancelled``)."""
        mine = set(self.in_hand())
        cutoff = utcnow() - timedelta(seconds=self.stale_after_s)
        with self.store.session() as session:
            rows = [b for b in session.scalars(select(Batch).where(
                Batch.status.in_(("queued", "running")), Batch.cancel_requested_at.is_(None),
                Batch.heartbeat_at.is_not(None), Batch.heartbeat_at < cutoff)) if b.id not in mine]
            for batch in rows:
                when = batch.heartbeat_at.strftime("%Y-%m-%d %H:%M:%S") if batch.heartbeat_at else "?"
                batch.status, batch.error = "interrupted", INTERRUPTED_BY_LOSS.format(when=f"{when} UTC")
            session.commit()
        if rows:
            log.warning("batch(es) abandoned by a stopped server marked interrupted: %s",
                        ", ".join(str(b.id) for b in rows))
        return [b.id for b in rows]
