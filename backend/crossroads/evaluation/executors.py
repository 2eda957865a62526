"""Where a batch's episodes run: local worker processes (default) or Ray actors.

Both executors drive the same :class:`EpisodeWorker`: one per process, holding one
:class:`~crossroads.sim.world.World` (libsumo runs one simulation per process) and one
controller, reused for every episode that worker gets, each episode in a child forked from the
worker (``FORK_EPISODES``: SUMO's results depend on the memory it runs in, and a fork of the
same worker gives every episode the same). A worker turns every Python exception of
an episode into an error report, and the executor turns a worker that dies (killed, segfault)
into an error report for the run it held and starts a replacement; so every task given to an
executor comes back as exactly one :class:`EpisodeReport`, unless the batch is cancelled (the
runs in flight are then dropped, not reported, and run again on resume). With ``wall_limit_s``, an
episode still running after that much wall-clock time has its worker killed and comes back as an
error report whose message starts with ``wall-clock limit`` (a stuck or endless episode must not
hold a worker for ever).

Executors hand reports to a callback in the calling thread, one at a time, as they arrive.
"""

from __future__ import annotations

import functools
import hashlib
import multiprocessing as mp
import os
import pickle
import shutil
import signal
import sys
import tempfile
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any, Literal, NoReturn, Protocol

from crossroads.settings import fork_episodes

FaultKind = Literal["raise", "kill"]
ERROR_MESSAGE_MAX = 4000  # [chars] of a stored error message (first line: type and message)
POLL_S = 0.2  # [s] how often executors look at the cancel event
FAULT_AT_STEP = 3  # an injected fault strikes at this decision of the episode


class ExecutorError(RuntimeError):
    """The executor cannot go on (e.g. its workers die before running anything)."""


@dataclass(frozen=True)
class EpisodeTask:
    """Run ``run_index`` of a batch, with its seed."""

    run_index: int
    seed: int


@dataclass(frozen=True)
class TraceFile:
    """A trace a worker wrote: path, size [bytes], sha256 (hex)."""

    path: str
    size_bytes: int
    sha256: str


@dataclass(frozen=True)
class EpisodeReport:
    """What came of one task: ``result`` (EpisodeResult JSON) or ``error`` (a message)."""

    run_index: int
    seed: int
    result: dict[str, Any] | None
    error: str | None
    wall_s: float  # [s] wall-clock time of the episode in its worker
    trace: TraceFile | None = None
    worker: str = ""

    @property
    def outcome(self) -> str:
        return "error" if self.result is None else str(self.result["outcome"])


@dataclass(frozen=True)
class WorkerJob:
    """Everything a worker needs to run a batch's episodes (picklable, small)."""

    spec: dict[str, Any]  # ScenarioSpec as JSON (model_dump(mode="json"))
    base_dir: str | None  # relative net paths of the spec count from here
    policy_ref: str  # a policy reference as crossroads.policy.ref.parse_policy reads it
    traces: Literal["all", "failed", "none"] = "failed"
    trace_dir: str | None = None  # <data_dir>/traces/<batch_id>; required unless traces == "none"
    # Test hook: run index → a fault injected mid-episode ("raise": an exception in the
    # controller; "kill": the worker process SIGKILLs itself). Empty in real use.
    faults: Mapping[int, FaultKind] = field(default_factory=dict)


def error_message(exc: BaseException) -> str:
    """``Type: message`` on the first line, then the traceback (bounded)."""
    head = f"{type(exc).__name__}: {exc}".strip()
    tb = "".join(traceback.format_exception(exc)).strip()
    text = f"{head}\n{tb}"
    return text if len(text) <= ERROR_MESSAGE_MAX else text[: ERROR_MESSAGE_MAX - 3] + "..."


class _Sabotaged:
    """A controller that fails on purpose at its FAULT_AT_STEP-th decision (tests only)."""

    def __init__(self, inner: Any, fault: FaultKind) -> None:
        self.inner, self.fault, self.name, self._calls = inner, fault, getattr(inner, "name", "?"), 0

    def reset(self, candidates: Any) -> None:
        self._calls = 0
        self.inner.reset(candidates)

    def decide(self, observation: Any) -> Any:
        self._calls += 1
        if self._calls == FAULT_AT_STEP:
            if self.fault == "kill":
                os.kill(os.getpid(), signal.SIGKILL)
            raise RuntimeError("injected fault (test hook)")
        return self.inner.decide(observation)


# Each episode runs in a child forked from its worker process, which has loaded the controller and
# built the World but never started SUMO. Why: SUMO's simulation depends on where its objects land in
# memory, so an episode run after others in the same process could end differently from the same
# seed run first (seed 2090914255 of the nominal left turn: timeout first, passed after three other
# episodes or after 5 000 throw-away allocations; docs/tried/world.md). A local worker
# does nothing between its forks but wait for the child (the child reads the task and sends the
# report itself), so every child starts from the same memory, whatever ran before it and whichever
# worker gets the seed. Off where there is no fork (Windows), or with CROSSROADS_FORK_EPISODES=0
# (read by each worker process when it starts): episodes then run in the worker itself.
FORK_EPISODES = hasattr(os, "fork") and fork_episodes()
_PR_SET_PDEATHSIG = 1  # prctl option (Linux): a signal for this process when its parent dies
_CHILD_STOP = 3  # exit status of a child that was told to stop (or lost the coordinator's pipe)
_CHILD_FAILED = 70  # exit status of a child that raised outside the episode (EX_SOFTWARE)


@dataclass(frozen=True)
class ChildDied:
    """What a local worker sends when the child running its task dies without a report."""

    who: str
    why: str


class EpisodeWorker:
    """Runs episodes of one job in this process: builds the World and controller once, lazily,
    and again only after an episode crashed (its SUMO session may be unusable). The executors run
    each episode in a child forked from the worker (``FORK_EPISODES``, :func:`_process_main`,
    :meth:`run_forked`)."""

    def __init__(self, job: WorkerJob) -> None:
        self.job = job
        self.name = f"pid {os.getpid()}"
        self._world: Any = None
        self._controller: Any = None
        self._spec: Any = None

    def prepare(self) -> None:
        """Load the controller and build the World now (SUMO is not started), so that forked
        children inherit them; a failure is left for the episode to record."""
        if sys.platform.startswith("linux"):
            _libc()  # loaded here once, not in every child (:func:`_die_with_parent`)
        try:
            self._ready()
        except Exception:  # noqa: BLE001 - run() records it as the episode's error
            pass

    def run_forked(self, task: EpisodeTask) -> EpisodeReport:
        """:meth:`run` in a child forked from this process, the report handed back through a pipe
        (a child that dies comes back as an error report naming how). This process reads the
        report between forks, so its memory is not quite the same for every child: the local
        workers avoid that (:func:`_process_main`); Ray's actors use this."""
        if not FORK_EPISODES:
            return self.run(task)
        self.prepare()
        read_fd, write_fd = os.pipe()
        parent = os.getpid()
        pid = os.fork()
        if pid == 0:
            status = _CHILD_FAILED
            try:
                os.close(read_fd)
                _die_with_parent(parent)
                data = pickle.dumps(self.run(task), protocol=pickle.HIGHEST_PROTOCOL)
                with os.fdopen(write_fd, "wb") as out:
                    out.write(data)
                status = 0
            finally:
                os._exit(status)
        os.close(write_fd)
        with os.fdopen(read_fd, "rb") as pipe:
            data = pipe.read()
        code = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
        if code == 0 and data:
            report: EpisodeReport = pickle.loads(data)
            return report
        return _died(task, f"episode process {pid} of {self.name}", _exit_reason(code))

    def _ready(self) -> tuple[Any, Any]:
        from crossroads.evaluation.policies import load_controller
        from crossroads.policy.ref import parse_policy
        from crossroads.scenario.spec import to_world_config, validate_scenario
        from crossroads.sim.world import World

        if self._spec is None:
            self._spec = validate_scenario(self.job.spec, source="batch scenario",
                                           check_references=False)
        if self._controller is None:
            self._controller = load_controller(parse_policy(self.job.policy_ref))
            if "torch" in sys.modules:  # a trained policy: one worker, one core (K workers on K cores);
                sys.modules["torch"].set_num_threads(1)  # torch's default would oversubscribe them
        if self._world is None:
            self._world = World(to_world_config(self._spec, base_dir=self.job.base_dir))
        return self._world, self._controller

    def _discard_world(self) -> None:
        world, self._world = self._world, None
        if world is not None:
            try:
                world.close()
            except Exception:  # noqa: BLE001 - it is being thrown away
                pass

    def run(self, task: EpisodeTask) -> EpisodeReport:
        """One episode in this process; never raises for a failure of the episode itself."""
        from crossroads.evaluation.episode import run_episode
        from crossroads.evaluation.trace import TraceRecorder

        start = time.perf_counter()
        recorder = TraceRecorder() if self.job.traces != "none" else None
        result: dict[str, Any] | None = None
        error: str | None = None
        try:
            world, controller = self._ready()
            fault = self.job.faults.get(task.run_index)
            if fault is not None:
                controller = _Sabotaged(controller, fault)
            episode = run_episode(world, controller, task.seed, recorder=recorder,
                                  scenario_name=self._spec.name)
            result = episode.to_json()
        except Exception as exc:  # noqa: BLE001 - recorded as the episode's error
            error = error_message(exc)
            self._discard_world()
        wall = time.perf_counter() - start
        trace = None
        if recorder is not None and (self.job.traces == "all" or result is None
                                     or result["outcome"] != "passed"):
            trace = self._save_trace(recorder, task)
        return EpisodeReport(task.run_index, task.seed, result, error, round(wall, 4), trace, self.name)

    def _save_trace(self, recorder: Any, task: EpisodeTask) -> TraceFile | None:
        """Write the trace (a partial one for a crashed episode) atomically; None if impossible."""
        if self.job.trace_dir is None:
            return None
        try:
            trace = recorder.trace()
        except Exception:  # noqa: BLE001 - the episode crashed before its trace had a header
            return None
        final = Path(self.job.trace_dir) / f"{task.run_index}.trace.npz"
        tmp = final.with_name(f".{final.name}.{os.getpid()}.tmp")
        trace.save(tmp)
        os.replace(tmp, final)
        data = final.read_bytes()
        return TraceFile(str(final), len(data), hashlib.sha256(data).hexdigest())

    def close(self) -> None:
        self._discard_world()


@functools.cache
def _libc() -> Any:
    """The C library, loaded once per worker (its forked children inherit it)."""
    import ctypes

    return ctypes.CDLL(None, use_errno=True)


def _die_with_parent(parent: int) -> None:
    """Have the kernel kill this process when its parent dies (Linux; elsewhere nothing): a worker
    killed on cancel must not leave its episode running on."""
    if not sys.platform.startswith("linux"):
        return
    _libc().prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)


ReportSink = Callable[[EpisodeReport], None]


class Executor(Protocol):
    """Runs tasks, reporting each as it finishes; returns when all are reported or on cancel."""

    workers: int

    @property
    def description(self) -> str: ...

    def run(self, job: WorkerJob, tasks: Iterable[EpisodeTask], report: ReportSink,
            cancel: threading.Event) -> None: ...


def _died(task: EpisodeTask, who: str, why: str) -> EpisodeReport:
    return EpisodeReport(task.run_index, task.seed, None, f"WorkerDied: {who} {why}", 0.0, None, who)


WALL_LIMIT_ERROR = "wall-clock limit"  # how an episode stopped for running too long is recorded


def _overran(task: EpisodeTask, who: str, limit_s: float) -> EpisodeReport:
    message = f"{WALL_LIMIT_ERROR}: the episode ran longer than {limit_s:g} s and was stopped ({who})"
    return EpisodeReport(task.run_index, task.seed, None, message, round(limit_s, 4), None, who)


# --- local processes ----------------------------------------------------------------------------


def adopt_scratch_dir(path: str) -> None:
    """Make ``path`` this process's temporary directory (``tempfile.tempdir``, inherited by its
    forked children): the World's files land there, and its coordinator removes it with the
    process, even when it had to kill it (:class:`WorkerProcess`)."""
    tempfile.tempdir = path


def _process_main(job: WorkerJob, conn: Connection, scratch: str) -> None:
    """A worker process: receive tasks, send reports, until None or the pipe closes. With
    ``FORK_EPISODES`` each task is received, run and reported by a child forked for it, and this
    process only waits for the child: it tells the coordinator when a child died (:class:`ChildDied`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    adopt_scratch_dir(scratch)
    worker = EpisodeWorker(job)
    try:
        if not FORK_EPISODES:
            while True:
                task = conn.recv()
                if task is None:
                    break
                conn.send(worker.run(task))
            return
        worker.prepare()
        parent = os.getpid()
        while True:
            pid = os.fork()
            if pid == 0:
                _episode_child(worker, conn, parent)
            code = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
            if code == _CHILD_STOP:
                break
            if code != 0:
                conn.send(ChildDied(f"episode process {pid} of {worker.name}", _exit_reason(code)))
    except (EOFError, OSError):
        pass
    finally:
        worker.close()
        conn.close()


def _episode_child(worker: EpisodeWorker, conn: Connection, parent: int) -> NoReturn:
    """A forked child of a worker: receive one task, run it, send its report, exit (``_CHILD_STOP``
    when told to stop or when the coordinator has gone)."""
    status = _CHILD_FAILED
    try:
        _die_with_parent(parent)
        try:
            task = conn.recv()
        except (EOFError, OSError):
            task = None
        if task is None:
            status = _CHILD_STOP
        else:
            conn.send(worker.run(task))
            status = 0
    finally:
        os._exit(status)


STOP_WAIT_S = 5.0  # [s] a worker process told to stop gets this long before it is killed


class WorkerProcess:
    """One worker process, its pipe and its scratch directory. ``target(*args, conn, scratch)``
    runs in the process; the scratch directory (its temporary files: the World's routes, SUMO's
    outputs) is removed when the process is stopped, also when it had to be killed mid-episode,
    when nothing in it could clean up after itself."""

    def __init__(self, ctx: Any, target: Callable[..., None], args: tuple[Any, ...], name: str) -> None:
        self.scratch = tempfile.mkdtemp(prefix="crossroads-worker-")
        self.conn, child = ctx.Pipe(duplex=True)
        self.process = ctx.Process(target=target, args=(*args, child, self.scratch), daemon=True, name=name)
        self.process.start()
        child.close()

    @property
    def who(self) -> str:
        return f"worker process {self.process.pid}"

    def alive(self) -> bool:
        return self.process.is_alive()

    def stop(self, *, force: bool) -> None:
        """Ask the process to stop (None down its pipe), or kill it (``force``); kill it anyway
        after STOP_WAIT_S; then remove its scratch directory."""
        if self.process.is_alive():
            if force:
                self.process.kill()
            else:
                try:
                    self.conn.send(None)
                except OSError:
                    self.process.kill()
        self.process.join(timeout=STOP_WAIT_S)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.conn.close()
        shutil.rmtree(self.scratch, ignore_errors=True)


class _Slot(WorkerProcess):
    """A batch worker process and the task it runs."""

    def __init__(self, ctx: Any, job: WorkerJob) -> None:
        super().__init__(ctx, _process_main, (job,), "crossroads-episode-worker")
        self.task: EpisodeTask | None = None
        self.started = 0.0  # [s] time.monotonic() when the task was sent


def _exit_reason(code: int | None) -> str:
    if code is not None and code < 0:
        try:
            return f"was killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"was killed by signal {-code}"
    return f"exited with code {code}"


class ProcessExecutor:
    """K local worker processes (spawn context), one task each at a time; ``wall_limit_s``: see
    the module docstring."""

    def __init__(self, workers: int | None = None, wall_limit_s: float | None = None) -> None:
        self.workers = max(1, workers or os.cpu_count() or 1)
        self.wall_limit_s = wall_limit_s
        self._pids: list[int] = []

    @property
    def description(self) -> str:
        return "local"

    def worker_pids(self) -> list[int]:
        """The pids of the live workers (for monitoring and tests)."""
        return list(self._pids)

    def run(self, job: WorkerJob, tasks: Iterable[EpisodeTask], report: ReportSink,
            cancel: threading.Event) -> None:
        pending = deque(tasks)
        if not pending:
            return
        ctx = mp.get_context("spawn")
        slots = [_Slot(ctx, job) for _ in range(min(self.workers, len(pending)))]
        deaths_without_progress = 0
        try:
            for slot in slots:
                self._dispatch(slot, pending)
            while any(s.task is not None for s in slots):
                self._pids = [s.process.pid for s in slots if s.process.pid is not None]
                if cancel.is_set():
                    return
                busy = [s for s in slots if s.task is not None]
                ready = wait([s.conn for s in busy] + [s.process.sentinel for s in busy], timeout=POLL_S)
                for i, slot in enumerate(slots):
                    if slot.task is None:
                        continue
                    got = None
                    if slot.conn in ready:
                        try:
                            got = slot.conn.recv()
                        except (EOFError, OSError):
                            got = None
                    if isinstance(got, ChildDied):  # the worker lives on: its next child takes the next task
                        task, slot.task = slot.task, None
                        report(_died(task, got.who, got.why))
                    elif got is not None:
                        slot.task = None
                        deaths_without_progress = 0
                        report(got)
                    elif slot.process.sentinel in ready or not slot.process.is_alive():
                        slot.process.join(timeout=1.0)
                        task, slot.task = slot.task, None
                        report(_died(task, slot.who, _exit_reason(slot.process.exitcode)))
                        deaths_without_progress += 1
                        if deaths_without_progress > 3 * self.workers:
                            raise ExecutorError(
                                f"{deaths_without_progress} worker processes died in a row; "
                                f"last: {slot.who} {_exit_reason(slot.process.exitcode)}")
                        slot.stop(force=True)
                        slots[i] = slot = _Slot(ctx, job) if pending else slot
                    elif self.wall_limit_s is not None and time.monotonic() - slot.started > self.wall_limit_s:
                        task, slot.task = slot.task, None
                        report(_overran(task, slot.who, self.wall_limit_s))
                        slot.stop(force=True)
                        slots[i] = slot = _Slot(ctx, job) if pending else slot
                    if slot.task is None and pending and not cancel.is_set():
                        if not slot.process.is_alive():  # died while idle: no run lost
                            slot.stop(force=True)
                            slots[i] = slot = _Slot(ctx, job)
                        self._dispatch(slot, pending)
        finally:
            for slot in slots:
                slot.stop(force=cancel.is_set() or slot.task is not None)
            self._pids = []

    def _dispatch(self, slot: _Slot, pending: deque[EpisodeTask]) -> None:
        task = pending.popleft()
        slot.task = task
        slot.started = time.monotonic()
        try:
            slot.conn.send(task)
        except OSError:  # it died between tasks: the sentinel reports the task as an error
            pass


# --- Ray ----------------------------------------------------------------------------------------


class _RayEpisodeActor:
    """A Ray actor around one EpisodeWorker (its own process, its own World)."""

    def __init__(self, job: WorkerJob) -> None:
        self.worker = EpisodeWorker(job)
        self.worker.name = f"ray actor pid {os.getpid()}"

    def run(self, task: EpisodeTask) -> EpisodeReport:
        return self.worker.run_forked(task)

    def pid(self) -> int:
        return os.getpid()


class RayExecutor:
    """K Ray actors. ``address``: a cluster (``ray://host:10001``, ``auto``) or ``local`` to start
    a local Ray for the batch. When Ray is already initialised in this process it is used as is
    (and left running); a Ray this executor started is shut down at the end.

    Traces are written by the actors to ``trace_dir``: on a multi-node cluster it must be a
    shared file system.
    """

    def __init__(self, address: str, workers: int | None = None, wall_limit_s: float | None = None) -> None:
        self.address = address
        self.workers = max(1, workers or os.cpu_count() or 1)
        self.wall_limit_s = wall_limit_s

    @property
    def description(self) -> str:
        return f"ray:{self.address}"

    def run(self, job: WorkerJob, tasks: Iterable[EpisodeTask], report: ReportSink,
            cancel: threading.Event) -> None:
        import ray
        from ray.exceptions import RayActorError, RayError

        pending = deque(tasks)
        if not pending:
            return
        started = False
        if not ray.is_initialized():
            if self.address == "local":
                ray.init(num_cpus=self.workers, include_dashboard=False, log_to_driver=False)
            else:
                ray.init(address=self.address, log_to_driver=False)
            started = True
        actor_class = ray.remote(num_cpus=1, max_restarts=0)(_RayEpisodeActor)
        actors = [actor_class.remote(job) for _ in range(min(self.workers, len(pending)))]
        inflight: dict[Any, tuple[int, EpisodeTask]] = {}
        started_at: dict[Any, float] = {}
        deaths_without_progress = 0

        def dispatch(index: int) -> None:
            if pending and not cancel.is_set():
                task = pending.popleft()
                ref = actors[index].run.remote(task)
                inflight[ref] = (index, task)
                started_at[ref] = time.monotonic()

        try:
            for index in range(len(actors)):
                dispatch(index)
            while inflight:
                if cancel.is_set():
                    return
                ready, _ = ray.wait(list(inflight), num_returns=1, timeout=POLL_S)
                if self.wall_limit_s is not None:  # overran: its actor is killed and replaced
                    now = time.monotonic()
                    for ref in [r for r in inflight if r not in ready and now - started_at[r] > self.wall_limit_s]:
                        index, task = inflight.pop(ref)
                        started_at.pop(ref, None)
                        ray.kill(actors[index])
                        actors[index] = actor_class.remote(job)
                        report(_overran(task, "ray actor", self.wall_limit_s))
                        dispatch(index)
                for ref in ready:
                    index, task = inflight.pop(ref)
                    started_at.pop(ref, None)
                    try:
                        got = ray.get(ref)
                        deaths_without_progress = 0
                    except RayActorError as exc:
                        got = _died(task, "ray actor", f"died: {str(exc).splitlines()[0]}")
                        deaths_without_progress += 1
                        if deaths_without_progress > 3 * len(actors):
                            raise ExecutorError(
                                f"{deaths_without_progress} Ray actors died in a row") from exc
                        actors[index] = actor_class.remote(job)
                    except RayError as exc:
                        got = EpisodeReport(task.run_index, task.seed, None, error_message(exc), 0.0)
                    report(got)
                    dispatch(index)
        finally:
            for actor in actors:
                try:
                    ray.kill(actor)
                except Exception:  # noqa: BLE001 - already gone
                    pass
            if started:
                ray.shutdown()
