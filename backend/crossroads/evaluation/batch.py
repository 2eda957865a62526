"""Batch evaluation: N seeded runs of a scenario with a policy, recorded run by run in the store.

    store = open_store(url)
    batch_id = create_batch_for(store, spec=spec, policy="rule", runs=200, base_dir=path.parent)
    summary = BatchRunner(store, batch_id, workers=2).run()          # blocking (the CLI)

    runner = BatchRunner(store, batch_id, on_progress=cb); runner.start()   # background (the API)
    runner.progress; runner.cancel(); runner.wait()

Run ``i`` gets seed ``run_seeds(spec, runs)[i]`` (the spec's base seed), so every policy meets the
same traffic run by run. Each finished episode is committed in its own transaction as its report
arrives; running a batch again skips the run indices already in the store, so an interrupted batch
resumes where it stopped and no run is ever run to completion and counted twice. An episode that
crashes (an exception, a SUMO error, a killed worker process) is recorded with outcome ``error``
and its message, and the batch goes on.

Traces (``traces``: all | failed | none; "failed" = every outcome but ``passed``) go to
``<data_dir>/traces/<batch_id>/<run_index>.trace.npz``, referenced from the episode's row.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Literal, NamedTuple

from crossroads.evaluation.background import BackgroundJob
from crossroads.evaluation.executors import (
    EpisodeReport,
    EpisodeTask,
    Executor,
    FaultKind,
    ProcessExecutor,
    RayExecutor,
    WorkerJob,
)
from crossroads.evaluation.metrics import is_blocked, wilson_interval
from crossroads.policy.identity import policy_identity
from crossroads.store import Store, crud
from crossroads.store.tables import EPISODE_OUTCOMES

TraceMode = Literal["all", "failed", "none"]
ProgressCallback = Callable[[int, int, EpisodeReport | None], None]  # (done, total, last report)


class BatchError(RuntimeError):
    """A batch cannot run (unknown id, its policy file changed, ...)."""


@dataclass(frozen=True)
class Progress:
    """Where a batch stands (``done`` counts runs recorded before this runner started too)."""

    batch_id: int
    status: str  # queued | running | done | cancelled | failed
    done: int
    total: int
    errors: int = 0
    passed: int = 0
    last: EpisodeReport | None = None

    @property
    def fraction(self) -> float:
        return self.done / self.total if self.total else 1.0


@dataclass(frozen=True)
class BatchResult:
    """The figures of a batch, from its recorded episodes.

    ``pass_rate`` = passed / (recorded − errors): an episode that crashed says nothing about the
    policy; ``wilson_low``/``wilson_high``: its Wilson 95 % interval
    (:func:`crossroads.evaluation.metrics.wilson_interval`). Travel time over the passed episodes:
    mean and sample standard deviation (ddof = 1; None below two) [s]. ``warnings``: what the
    batch's network gave reason to warn about when it was created (``batches.warnings``).
    """

    batch_id: int
    scenario: str
    policy: str
    status: str
    runs: int
    recorded: int
    errors: int
    passed: int
    pass_rate: float | None
    wilson_low: float
    wilson_high: float
    outcome_counts: dict[str, int]
    travel_time_mean_s: float | None
    travel_time_std_s: float | None
    travel_times_s: list[float] = field(repr=False, default_factory=list)
    warnings: list[str] = field(default_factory=list)
    blocked: int = 0  # timeouts blocked by the world (metrics.is_blocked); in the judged runs

    @property
    def judged(self) -> int:
        """Episodes that ended in an outcome of the policy (recorded − errors)."""
        return self.recorded - self.errors

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        data.pop("travel_times_s")
        data["judged"] = self.judged
        return data


def summarize_batch(store: Store, batch_id: int) -> BatchResult:
    """The :class:`BatchResult` of a stored batch (whatever its status)."""
    with store.session() as session:
        batch = crud.get_batch(session=session, batch_id=batch_id)
        if batch is None:
            raise BatchError(f"no batch {batch_id} in {store.url}")
        counts = crud.outcome_counts(session=session, batch_id=batch_id)
        travel = [e.travel_time_s for e in crud.batch_results(session=session, batch_id=batch_id,
                                                               outcomes=["passed"])
                  if e.travel_time_s is not None]
        blocked = sum(1 for e in crud.batch_results(session=session, batch_id=batch_id,
                                                    outcomes=["timeout"]) if is_blocked(e))
        recorded = sum(counts.values())
        errors = counts.get("error", 0)
        passed = counts.get("passed", 0)
        judged = recorded - errors
        low, high = wilson_interval(passed, judged)
        mean = math.fsum(travel) / len(travel) if travel else None
        std = (math.sqrt(math.fsum((t - mean) ** 2 for t in travel) / (len(travel) - 1))
               if mean is not None and len(travel) > 1 else None)
        return BatchResult(
            batch_id=batch.id, scenario=batch.scenario.name, policy=batch.policy.ref,
            status=batch.status, runs=batch.runs, recorded=recorded, errors=errors, passed=passed,
            pass_rate=passed / judged if judged else None, wilson_low=low, wilson_high=high,
            outcome_counts={o: counts.get(o, 0) for o in EPISODE_OUTCOMES},
            travel_time_mean_s=mean, travel_time_std_s=std, travel_times_s=travel,
            warnings=list(batch.warnings or []), blocked=blocked)


def create_batch_for(store: Store, *, spec: Any, policy: str, runs: int | None = None,
                     traces: TraceMode = "failed", base_dir: str | Path | None = None,
                     warnings: Sequence[str] | None = None) -> int:
    """Register ``spec`` and ``policy`` (idempotently) and a queued batch of ``runs`` (default
    ``spec.runs``) runs, with ``warnings``: by default those of its network as it is now
    (:func:`~crossroads.scenario.network_checks.batch_warnings`; a caller that has measured them
    for the same spec and base_dir passes them); returns its id."""
    if warnings is None:
        from crossroads.scenario.network_checks import batch_warnings

        warnings = batch_warnings(spec, base_dir)
    with store.session() as session:
        scenario = crud.get_or_create_scenario(session=session, spec=spec)
        pol = crud.get_or_create_policy(session=session, ref=policy)
        batch = crud.create_batch(session=session, scenario=scenario, policy=pol,
                                  runs=spec.runs if runs is None else runs, traces=traces,
                                  base_dir=base_dir, warnings=warnings)
        return batch.id


def make_executor(*, workers: int | None = None, ray_address: str | None = None) -> Executor:
    """Local processes, or Ray actors when ``ray_address`` is given (``local``: a local Ray)."""
    return RayExecutor(ray_address, workers) if ray_address else ProcessExecutor(workers)


class _Plan(NamedTuple):
    job: WorkerJob
    tasks: list[EpisodeTask]
    total: int
    done: int
    errors: int
    passed: int


class BatchRunner(BackgroundJob[BatchResult]):
    """Runs (or resumes) one stored batch. :meth:`run` blocks; :meth:`start` runs it in a
    background thread; :meth:`cancel` stops it soon (runs in flight are dropped and run again
    on resume); :attr:`progress` may be read from any thread.

    ``faults`` is a test hook: run index → "raise" | "kill" injected into that episode.
    """

    _error_type = BatchError

    def __init__(self, store: Store, batch_id: int, *, workers: int | None = None,
                 ray_address: str | None = None, data_dir: str | Path | None = None,
                 on_progress: ProgressCallback | None = None,
                 faults: Mapping[int, FaultKind] | None = None,
                 executor: Executor | None = None) -> None:
        super().__init__(f"batch {batch_id}")
        self.store = store
        self.batch_id = batch_id
        self.executor = executor or make_executor(workers=workers, ray_address=ray_address)
        if data_dir is None:
            from crossroads.settings import Settings

            data_dir = Settings().data_dir
        self.data_dir = Path(data_dir)
        self.on_progress = on_progress
        self.faults = dict(faults or {})
        self._lock = threading.Lock()
        self._progress = Progress(batch_id, "queued", 0, 0)

    # --- control ------------------------------------------------------------------------------

    @property
    def progress(self) -> Progress:
        with self._lock:
            return self._progress

    # --- running ------------------------------------------------------------------------------

    def _plan(self) -> _Plan:
        """Check the batch can run here: the worker job, the runs left, the counts so far."""
        from crossroads.evaluation.policies import load_controller
        from crossroads.policy.ref import parse_policy
        from crossroads.scenario.spec import run_seeds, to_world_config

        with self.store.session() as session:
            batch = crud.get_batch(session=session, batch_id=self.batch_id)
            if batch is None:
                raise BatchError(f"no batch {self.batch_id} in {self.store.url}")
            spec = crud.scenario_spec(scenario=batch.scenario)
            policy = batch.policy
            if policy.kind != "builtin":  # a file (checkpoint, ONNX) or a plugin's source
                now = policy_identity(policy.ref).file_hash
                if now != policy.file_hash:
                    raise BatchError(f"policy file {policy.ref} changed since batch {batch.id} "
                                     f"was created ({policy.file_hash} → {now}); start a new batch")
            done = crud.done_run_indices(session=session, batch_id=batch.id)
            counts = crud.outcome_counts(session=session, batch_id=batch.id)
            runs, base_seed, traces, base_dir = batch.runs, batch.base_seed, batch.traces, batch.base_dir
            status = batch.status
        # Fail here, once, on what would fail every episode: a network that cannot be built (also
        # warms the build cache before workers race for it) or a policy that cannot be loaded.
        to_world_config(spec, base_dir=base_dir)
        load_controller(parse_policy(policy.ref))
        seeds = run_seeds(spec.model_copy(update={"seed": base_seed}), runs)
        tasks = [EpisodeTask(i, seeds[i]) for i in range(runs) if i not in done]
        trace_dir = None
        if traces != "none":
            trace_dir = self.data_dir / "traces" / str(self.batch_id)
            trace_dir.mkdir(parents=True, exist_ok=True)
        job = WorkerJob(spec=spec.model_dump(mode="json"), base_dir=base_dir, policy_ref=policy.ref,
                        traces=traces, trace_dir=None if trace_dir is None else str(trace_dir),
                        faults=self.faults)
        with self._lock:
            self._progress = replace(self._progress, status=status)
        return _Plan(job, tasks, runs, len(done), counts.get("error", 0), counts.get("passed", 0))

    def _record(self, report: EpisodeReport) -> None:
        trace = None
        if report.trace is not None:
            trace = crud.TraceRef(size_bytes=report.trace.size_bytes, sha256=report.trace.sha256,
                                  path=report.trace.path)
        with self.store.session() as session:
            row = crud.record_episode(session=session, batch_id=self.batch_id,
                                      run_index=report.run_index, seed=report.seed,
                                      result=report.result, error=report.error, trace=trace,
                                      wall_s=report.wall_s)
        if row is None:  # already recorded (a concurrent runner): not counted again
            return
        with self._lock:
            p = self._progress
            self._progress = replace(p, done=p.done + 1, last=report,
                                     errors=p.errors + (report.outcome == "error"),
                                     passed=p.passed + (report.outcome == "passed"))
            p = self._progress
        if self.on_progress is not None:
            self.on_progress(p.done, p.total, report)

    def _set_status(self, status: str, error: str | None = None) -> None:
        with self.store.session() as session:
            crud.set_batch_status(session=session, batch_id=self.batch_id, status=status, error=error,
                                  workers=self.executor.workers if status == "running" else None,
                                  executor=self.executor.description if status == "running" else None)
        with self._lock:
            self._progress = replace(self._progress, status=status)

    def run(self) -> BatchResult:
        """Run every run of the batch not yet in the store; the batch's summary."""
        plan = self._plan()
        if not plan.tasks and self.progress.status == "done":  # nothing left, already finished
            self._summary = summarize_batch(self.store, self.batch_id)
            return self._summary
        with self._lock:
            self._progress = Progress(self.batch_id, "running", plan.done, plan.total,
                                      plan.errors, plan.passed)
        self._set_status("running")
        if self.on_progress is not None:
            self.on_progress(plan.done, plan.total, None)
        try:
            self.executor.run(plan.job, plan.tasks, self._record, self._cancel)
        except BaseException as exc:
            interrupted = isinstance(exc, KeyboardInterrupt)
            self._set_status("cancelled" if interrupted else "failed",
                             None if interrupted else f"{type(exc).__name__}: {exc}")
            raise
        self._set_status("cancelled" if self._cancel.is_set() else "done")
        self._summary = summarize_batch(self.store, self.batch_id)
        return self._summary


def evaluate(store: Store, *, spec: Any, policy: str, runs: int | None = None,
             workers: int | None = None, ray_address: str | None = None,
             traces: TraceMode = "failed", base_dir: str | Path | None = None,
             data_dir: str | Path | None = None,
             on_progress: ProgressCallback | None = None) -> BatchResult:
    """Create a batch of ``spec`` × ``policy`` and run it to the end (blocking)."""
    batch_id = create_batch_for(store, spec=spec, policy=policy, runs=runs, traces=traces,
                                base_dir=base_dir)
    return BatchRunner(store, batch_id, workers=workers, ray_address=ray_address,
                       data_dir=data_dir, on_progress=on_progress).run()
