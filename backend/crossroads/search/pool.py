"""Long-lived episode workers for a search: a trial no longer starts a worker process of its own.

A batch's worker process (:class:`~crossroads.evaluation.executors.ProcessExecutor`) is spawned
for its batch: Python, torch and the policy are loaded again in it. A search runs every trial as a
batch of one run, so it paid that start-up (about 3 s of CPU on the 2-core development machine,
as long as a short episode) for every episode. Here each of ``workers`` processes is started once
for the whole search and, for every trial it is given, forks a child that receives the trial's
job and seed, runs it with :class:`~crossroads.evaluation.executors.EpisodeWorker` exactly as a
batch worker does (load the policy, build the World, run the episode, save its trace) and sends
the report back. The long-lived process has imported everything and loaded the policy once (so
the child's loading is a warm one) and does nothing between forks but wait: every child starts
from the same memory, whichever process runs it and whatever ran before (the reason a batch
worker forks its episodes too: SUMO's result can depend on where its objects land in memory;
docs/tried/world.md). So the same trial gives the same episode however the search is scheduled,
and the same episode ``crossroads evaluate`` gives on its scenario (checked by
tests/search/test_pool.py and by the throughput comparison of benchmarks/failure_search.py).

Needs ``fork`` (``crossroads.evaluation.executors.FORK_EPISODES``); where there is none the search
runs its trials through the batch executors as before. :class:`PoolExecutor` puts the pool behind
the :class:`~crossroads.evaluation.executors.Executor` protocol, so each trial is still stored
and recorded by :class:`~crossroads.evaluation.batch.BatchRunner` as a batch of one run.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import signal
import sys
import threading
import time
from collections.abc import Iterable
from multiprocessing.connection import Connection, wait
from typing import Any, NoReturn

from crossroads.evaluation.executors import (
    _CHILD_FAILED,
    _CHILD_STOP,
    POLL_S,
    ChildDied,
    EpisodeReport,
    EpisodeTask,
    EpisodeWorker,
    ExecutorError,
    ReportSink,
    WorkerJob,
    WorkerProcess,
    _die_with_parent,
    adopt_scratch_dir,
    _died,
    _exit_reason,
    _libc,
    _overran,
)



def _warm(policy_ref: str) -> None:
    """Import what every episode needs and load the policy once, so that a child's own loading
    finds its modules imported and its files in the page cache."""
    from crossroads.evaluation.episode import run_episode  # noqa: F401 - imported to warm
    from crossroads.evaluation.policies import load_controller
    from crossroads.evaluation.trace import TraceRecorder  # noqa: F401 - imported to warm
    from crossroads.policy.ref import parse_policy
    from crossroads.sim.world import World  # noqa: F401 - imported to warm

    try:
        load_controller(parse_policy(policy_ref))
    except Exception:  # noqa: BLE001 - each episode loads it again and records why it cannot
        pass
    if "torch" in sys.modules:  # as a batch worker: one thread. Also what lets the forked children
        sys.modules["torch"].set_num_threads(1)  # use torch: OpenMP's threads do not survive a fork


def _pool_main(policy_ref: str, conn: Connection, scratch: str) -> None:
    """A long-lived worker: warm up, then fork one child per trial and wait for it, until a child
    is told to stop (or the coordinator's pipe closes). A child that dies without a report is told
    to the coordinator (:class:`ChildDied`); the next child takes the next trial."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the coordinator's to handle
    adopt_scratch_dir(scratch)
    if sys.platform.startswith("linux"):
        _libc()  # loaded once here, not in every child
    _warm(policy_ref)
    parent = os.getpid()
    try:
        while True:
            pid = os.fork()
            if pid == 0:
                _trial_child(conn, parent)
            code = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
            if code == _CHILD_STOP:
                break
            if code != 0:
                conn.send(ChildDied(f"episode process {pid} of worker pid {parent}", _exit_reason(code)))
    except (EOFError, OSError):
        pass
    finally:
        conn.close()


def _trial_child(conn: Connection, parent: int) -> NoReturn:
    """A forked child: receive one (job, task), run it as a batch worker would, send the report,
    leave nothing behind (its World's files), exit."""
    status = _CHILD_FAILED
    try:
        _die_with_parent(parent)
        try:
            message = conn.recv()
        except (EOFError, OSError):
            message = None
        if message is None:
            status = _CHILD_STOP
        else:
            job, task = message
            worker = EpisodeWorker(job)
            worker.name = f"pid {os.getpid()} (search worker pid {parent})"
            report = worker.run(task)
            worker.close()
            conn.send(report)
            status = 0
    finally:
        os._exit(status)


class _Worker(WorkerProcess):
    """One long-lived search worker process (:func:`_pool_main`) and its pipe."""

    def __init__(self, ctx: Any, policy_ref: str) -> None:
        super().__init__(ctx, _pool_main, (policy_ref,), "crossroads-search-worker")

    @property
    def who(self) -> str:
        return f"search worker process {self.process.pid}"


class TrialPool:
    """``workers`` long-lived worker processes; :meth:`run` runs one episode on a free one (from
    any thread; it waits for one to be free). A worker that dies is replaced; ``wall_limit_s``
    stops an episode that runs longer (its worker killed and replaced), as the batch executors do.
    Close it (or use it as a context manager) to stop the processes."""

    def __init__(self, policy_ref: str, workers: int, *, wall_limit_s: float | None = None) -> None:
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.policy_ref = policy_ref
        self.workers = workers
        self.wall_limit_s = wall_limit_s
        self._ctx = mp.get_context("spawn")
        self._idle: queue.Queue[_Worker | None] = queue.Queue()
        self._all: list[_Worker] = []
        self._lock = threading.Lock()
        self._closed = False
        self._deaths_in_a_row = 0
        for _ in range(workers):  # started at once: they warm up side by side
            self._idle.put(self._start())

    def _start(self) -> _Worker:
        worker = _Worker(self._ctx, self.policy_ref)
        with self._lock:
            self._all.append(worker)
        return worker

    def _retire(self, worker: _Worker, *, force: bool) -> None:
        worker.stop(force=force)
        with self._lock:
            if worker in self._all:
                self._all.remove(worker)

    def worker_pids(self) -> list[int]:
        """The pids of the live worker processes (for monitoring and tests)."""
        with self._lock:
            return [w.process.pid for w in self._all if w.process.pid is not None and w.alive()]

    def run(self, job: WorkerJob, task: EpisodeTask, cancel: threading.Event) -> EpisodeReport | None:
        """Run ``task`` of ``job`` on a free worker; its report, or None when ``cancel`` was set
        first (the episode is then dropped, its worker killed)."""
        worker = self._idle.get()
        try:
            if self._closed:
                raise ExecutorError("the search's worker pool is closed")
            if worker is None or not worker.alive():
                if worker is not None:
                    self._retire(worker, force=True)
                worker = self._start()
            return self._run_on(worker, job, task, cancel)
        finally:
            self._idle.put(worker)

    def _run_on(self, worker: _Worker, job: WorkerJob, task: EpisodeTask,
                cancel: threading.Event) -> EpisodeReport | None:
        try:
            worker.conn.send((job, task))
        except OSError:  # died while idle: the sentinel below reports it
            pass
        started = time.monotonic()
        while True:
            if cancel.is_set():
                self._retire(worker, force=True)
                return None
            ready = wait([worker.conn, worker.process.sentinel], timeout=POLL_S)
            got: Any = None
            if worker.conn in ready:
                try:
                    got = worker.conn.recv()
                except (EOFError, OSError):
                    got = None
            if isinstance(got, ChildDied):  # the worker lives on
                return _died(task, got.who, got.why)
            if got is not None:
                with self._lock:
                    self._deaths_in_a_row = 0
                report: EpisodeReport = got
                return report
            if worker.process.sentinel in ready or not worker.alive():
                worker.process.join(timeout=1.0)
                report = _died(task, worker.who, _exit_reason(worker.process.exitcode))
                self._retire(worker, force=True)
                with self._lock:
                    self._deaths_in_a_row += 1
                    deaths = self._deaths_in_a_row
                if deaths > 3 * self.workers:
                    raise ExecutorError(f"{deaths} search worker processes died in a row; last: "
                                        f"{report.error}")
                return report
            if self.wall_limit_s is not None and time.monotonic() - started > self.wall_limit_s:
                self._retire(worker, force=True)
                return _overran(task, worker.who, self.wall_limit_s)

    def close(self) -> None:
        """Stop every worker (those busy are killed)."""
        self._closed = True
        with self._lock:
            workers = list(self._all)
        for worker in workers:
            self._retire(worker, force=False)

    def __enter__(self) -> TrialPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class PoolExecutor:
    """The :class:`~crossroads.evaluation.executors.Executor` protocol over a shared
    :class:`TrialPool`: what :class:`~crossroads.evaluation.batch.BatchRunner` runs one trial's
    batch with. Its tasks run one after the other (a trial is a batch of one run; the search runs
    its trials side by side)."""

    workers = 1

    def __init__(self, pool: TrialPool) -> None:
        self.pool = pool

    @property
    def description(self) -> str:
        return "local (search pool)"

    def run(self, job: WorkerJob, tasks: Iterable[EpisodeTask], report: ReportSink,
            cancel: threading.Event) -> None:
        for task in tasks:
            if cancel.is_set():
                return
            got = self.pool.run(job, task, cancel)
            if got is None:
                return
            report(got)
