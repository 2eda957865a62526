"""Running a search: optuna proposes points of the space, each one episode as a stored batch.

    search_id = create_search_for(store, space=space, policy="models/apg.pt+shield", budget=300)
    summary = SearchRunner(store, search_id, workers=2).run()            # blocking (the CLI)
    SearchRunner(store, search_id, workers=2, executor="batch").run()    # a batch worker per trial
    runner = SearchRunner(store, search_id); runner.start(); runner.progress; runner.cancel()

**Episodes.** Each trial is the scenario :func:`~crossroads.search.space.scenario_for` makes (the
nominal one with the trial's values, one run, the trial's seed), stored and run as a batch of one
run by :class:`~crossroads.evaluation.batch.BatchRunner`: so it is recorded the way
``crossroads evaluate`` records that scenario's file, traces of failures included, and the studio
can play it back. Up to ``workers`` trials run at once, on the search's long-lived workers
(:mod:`crossroads.search.pool`: started once, each trial in a child forked from one, the episode a
fresh batch worker would give); with ``executor="batch"``, on Ray, or where there is no fork,
each trial starts a batch worker (a local process or a Ray actor) of its own, as a batch does.

**Search.** Optuna's TPE sampler (or its uniform random sampler, a baseline) proposes trial ``n``
from the trials 0 … n − L before it (L: the search's ``generation``), trials n − L + 1 … n − 1
still pending (``constant_liar`` keeps it away from them), with a sampler seeded from the search's
seed and ``n``; objectives (:mod:`crossroads.search.objective`) are told in trial order. So a search
is deterministic given its seed and generation size (and deterministic episodes), however many
workers run it and however long each episode takes, and a resumed search proposes exactly what an
uninterrupted one would: its stored trials are told again, not run again. There is no barrier
between generations: trial n is proposed, and a free worker takes it, as soon as trials 0 … n − L
are done, whatever the others of its "generation" are doing. The scenario seed of each trial is
drawn from the search's seed (:func:`~crossroads.search.space.draw_seed`), or, where the space
pools its seeds, proposed by the sampler as one more choice among the pool's
(:func:`~crossroads.search.space.seed_pool`).

**Shrinking.** Then every distinct failing trial is shrunk (:mod:`crossroads.search.shrink`), up
to ``shrink_steps`` episodes each, those episodes stored as trials too (numbers from ``budget``
on, ``shrink_steps`` per failure, so they do not depend on timing), and the minimal failing
scenario goes to the failures collection (:mod:`crossroads.search.collection`) and the store.
"""

from __future__ import annotations

import math
import os
import threading
import warnings
from collections import deque
from collections.abc import Callable, Mapping
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from crossroads.evaluation.background import BackgroundJob
from crossroads.evaluation.executors import FORK_EPISODES, Executor
from crossroads.policy.identity import policy_identity
from crossroads.scenario.spec import ScenarioSpec, content_hash
from crossroads.search import records
from crossroads.search.collection import write_failure
from crossroads.search.objective import FAILURE_VALUE, objective
from crossroads.search.pool import PoolExecutor, TrialPool
from crossroads.search.shrink import Shrinker
from crossroads.search.space import SEED_KEY, Space, draw_seed, scenario_for, seed_pool, validate_space
from crossroads.store import Store, crud
from crossroads.store.search_tables import SearchTrial

SAMPLER_STREAM = 0  # spawn key of the trials' sampler seeds (the trials' scenario seeds use 1)
EXECUTORS = ("pool", "batch")  # where trials run: long-lived search workers, or a batch worker each
TPE_STARTUP_TRIALS = 10  # TPE proposes uniformly at random until this many trials are told
PARAM_TOLERANCE = 1e-9  # a stored trial's value and the one proposed again must agree this well

SearchProgressCallback = Callable[["SearchProgress"], None]


class SearchError(RuntimeError):
    """A search cannot run (unknown id, its policy file changed, its stored trials disagree)."""


@dataclass(frozen=True)
class SearchProgress:
    """Where a search stands (counts include what was recorded before this runner started)."""

    search_id: int
    status: str  # queued | running | done | cancelled | failed
    phase: str  # search | shrink | done
    budget: int
    searched: int  # search episodes recorded
    shrink_episodes: int  # shrinking episodes recorded
    failing: int  # search episodes that failed
    failures: int  # shrunk failures in the collection
    to_shrink: int  # distinct failing trials to shrink (known once the search phase is over)
    best_objective: float | None

    @property
    def episodes(self) -> int:
        return self.searched + self.shrink_episodes

    def to_json(self) -> dict[str, Any]:
        return {**asdict(self), "episodes": self.episodes}


@dataclass(frozen=True)
class TrialResult:
    number: int
    outcome: str  # an episode outcome, or error
    objective: float | None
    result: dict[str, Any] | None = field(default=None, repr=False)


def create_search_for(store: Store, *, space: Space, policy: str, budget: int, sampler: str = "tpe",
                      seed: int = 0, generation: int = 2, shrink_steps: int | None = None,
                      failures_dir: str | Path | None = None) -> int:
    """Register a queued search of ``space`` for ``policy``; its id. ``shrink_steps`` defaults to
    two per parameter (one back to nominal, one halfway)."""
    if budget < 0:
        raise ValueError(f"budget must be >= 0, got {budget}")
    if generation < 1:
        raise ValueError(f"generation must be >= 1, got {generation}")
    steps = 2 * len(space.parameters) if shrink_steps is None else shrink_steps
    if steps < 0:
        raise ValueError(f"shrink_steps must be >= 0, got {steps}")
    with store.session() as session:
        row = records.create_search(session=session, name=space.space.name, policy=policy,
                                    space=space.to_json(), sampler=sampler, seed=seed,
                                    budget=budget, generation=generation, shrink_steps=steps,
                                    failures_dir=failures_dir)
        return row.id


def stored_space(space_json: Mapping[str, Any], search_id: int) -> Space:
    """The :class:`Space` of a stored search (its nominal scenario is inline)."""
    return validate_space(space_json, source=f"search {search_id}")


def _distributions(space: Space, pool: list[int] | None) -> dict[str, Any]:
    """Optuna's distribution of each parameter, and of the seed (``SEED_KEY``) when it is pooled."""
    from optuna.distributions import CategoricalDistribution, FloatDistribution, IntDistribution

    out: dict[str, Any] = {}
    if pool is not None:
        out[SEED_KEY] = CategoricalDistribution(pool)
    for p in space.parameters:
        if p.choices is not None:
            out[p.path] = CategoricalDistribution([p.cast(v) for v in p.choices])
        elif p.whole:
            out[p.path] = IntDistribution(int(p.low), int(p.high))  # type: ignore[arg-type]
        else:
            out[p.path] = FloatDistribution(float(p.low), float(p.high))  # type: ignore[arg-type]
    return out


@dataclass(frozen=True)
class FailureSplit:
    """TPE's split of the told trials into its good side and the rest (optuna's ``gamma``): optuna's
    default share (10 %, at most 25 trials), and at least every failure told so far.

    Why: every failure scores the same (``FAILURE_VALUE``) and optuna breaks ties by trial order, so
    with its default split only the first few failures were on the good side, frozen there once 25
    had been found, and every later failure counted *against* its own region. With every failure on
    the good side, TPE's ratio of the two densities follows the chance of failing, in every region
    where failures were found, not only around the first ones."""

    failing: int  # failures among the trials told

    def __call__(self, told: int) -> int:
        return max(min(math.ceil(0.1 * told), 25), self.failing)


def make_sampler(kind: str, seed: int, failing: int = 0) -> Any:
    """Optuna's sampler for one trial: TPE (multivariate, constant liar, the good side holding
    every one of the ``failing`` failures told so far: :class:`FailureSplit`) or uniform random."""
    from optuna.samplers import RandomSampler, TPESampler

    if kind == "random":
        return RandomSampler(seed=seed)
    if kind != "tpe":
        raise ValueError(f"unknown sampler {kind!r}")
    with warnings.catch_warnings():  # multivariate TPE is marked experimental
        warnings.simplefilter("ignore")
        return TPESampler(seed=seed, multivariate=True, constant_liar=True,
                          n_startup_trials=TPE_STARTUP_TRIALS, gamma=FailureSplit(failing),
                          warn_independent_sampling=False)


def trial_sampler_seed(search_seed: int, number: int) -> int:
    """The seed of the sampler that proposes trial ``number`` of a search."""
    state = np.random.SeedSequence(search_seed, spawn_key=(SAMPLER_STREAM, number))
    return int(state.generate_state(1, np.uint32)[0])


def _same_params(a: Mapping[str, Any], b: Mapping[str, Any]) -> bool:
    return a.keys() == b.keys() and all(
        math.isclose(float(a[k]), float(b[k]), rel_tol=0.0, abs_tol=PARAM_TOLERANCE) for k in a)


def trial_name(space_name: str, search_id: int, number: int) -> str:
    """The scenario name of trial ``number`` (the name its failure file keeps)."""
    return f"{space_name}-s{search_id}-t{number}"


def distinct_key(spec: ScenarioSpec) -> str:
    """What makes two failing scenarios the same: the spec's content hash, its name left out."""
    return content_hash(spec.model_copy(update={"name": "failure", "description": ""}))


class SearchRunner(BackgroundJob[dict[str, Any]]):
    """Runs (or resumes) one stored search. :meth:`run` blocks; :meth:`start` runs it in a
    background thread; :meth:`cancel` stops it soon (episodes in flight are dropped and run again
    on resume); :attr:`progress` may be read from any thread."""

    _error_type = SearchError

    def __init__(self, store: Store, search_id: int, *, workers: int | None = None,
                 ray_address: str | None = None, data_dir: str | Path | None = None,
                 on_progress: SearchProgressCallback | None = None,
                 shrink_limit: int | None = None, executor: str = "pool") -> None:
        super().__init__(f"search {search_id}")
        if executor not in EXECUTORS:
            raise ValueError(f"executor must be one of {', '.join(EXECUTORS)}, got {executor!r}")
        self.executor = executor
        self._pool: TrialPool | None = None
        self.store = store
        self.shrink_limit = shrink_limit  # shrink only the first this many failures (None: all)
        self.search_id = search_id
        self.workers = max(1, workers or os.cpu_count() or 1)
        self.ray_address = ray_address
        if data_dir is None:
            from crossroads.settings import Settings

            data_dir = Settings().data_dir
        self.data_dir = Path(data_dir)
        self.on_progress = on_progress
        self._lock = threading.Lock()
        self._active: set[Any] = set()  # the BatchRunners in flight (to cancel them)
        self._progress = SearchProgress(search_id, "queued", "search", 0, 0, 0, 0, 0, 0, None)

    # --- control ------------------------------------------------------------------------------

    @property
    def progress(self) -> SearchProgress:
        with self._lock:
            return self._progress

    def cancel(self) -> None:
        super().cancel()
        with self._lock:
            active = list(self._active)
        for runner in active:
            runner.cancel()

    def _update(self, **changes: Any) -> None:
        with self._lock:
            self._progress = replace(self._progress, **changes)
            progress = self._progress
        if self.on_progress is not None:
            self.on_progress(progress)

    def _count_trial(self, kind: str, result: TrialResult) -> None:
        with self._lock:
            p = self._progress
            if kind == "search":
                best = p.best_objective
                if result.objective is not None and (best is None or result.objective < best):
                    best = result.objective
                self._progress = replace(p, searched=p.searched + 1, best_objective=best,
                                         failing=p.failing + (result.objective == FAILURE_VALUE))
            else:
                self._progress = replace(p, shrink_episodes=p.shrink_episodes + 1)
            progress = self._progress
        if self.on_progress is not None:
            self.on_progress(progress)

    # --- running ------------------------------------------------------------------------------

    def run(self) -> dict[str, Any]:
        """Run what is left of the search; its summary (:func:`summarize_search`)."""
        import optuna

        from crossroads.scenario.network_checks import batch_warnings

        optuna.logging.set_verbosity(optuna.logging.WARNING)
        with self.store.session() as session:
            search = records.get_search(session=session, search_id=self.search_id)
            if search is None:
                raise SearchError(f"no search {self.search_id} in {self.store.url}")
            policy = search.policy
            if policy.kind != "builtin":
                now = policy_identity(policy.ref).file_hash
                if now != policy.file_hash:
                    raise SearchError(f"policy file {policy.ref} changed since search {search.id} "
                                      f"was created ({policy.file_hash} → {now}); start a new search")
            self.policy_ref = policy.ref
            self.space = stored_space(search.space, search.id)
            self.sampler, self.seed = search.sampler, search.seed
            self.budget, self.generation = search.budget, search.generation
            self.shrink_steps = search.shrink_steps
            failures_dir = search.failures_dir
            if failures_dir is None:
                failures_dir = str(self.data_dir / "failures" / f"{search.name}-{search.id}")
                records.set_failures_dir(session=session, search_id=search.id, path=failures_dir)
            self.failures_dir = Path(failures_dir)
            stored = records.trials(session=session, search_id=search.id)
            recorded_failures = len(records.failures(session=session, search_id=search.id))
        self._stored = {t.number: t for t in stored}
        done = [t for t in stored if t.outcome is not None]
        objectives = [t.objective for t in done if t.kind == "search" and t.objective is not None]
        self._progress = SearchProgress(
            self.search_id, "running", "search", self.budget,
            searched=sum(t.kind == "search" for t in done),
            shrink_episodes=sum(t.kind == "shrink" for t in done),
            failing=sum(t.kind == "search" and t.objective == FAILURE_VALUE for t in done),
            failures=recorded_failures, to_shrink=0,
            best_objective=min(objectives) if objectives else None)
        self._warnings = batch_warnings(self.space.nominal, None)  # one network for every trial
        self._description = (f"Search {self.search_id} of {self.space.space.name} for "
                             f"{self.policy_ref}: one episode of the space.")
        self._set_status("running")
        ray_started = self._start_ray()
        try:
            self._search_phase()
            if not self.cancelled:
                self._shrink_phase()
        except BaseException as exc:
            interrupted = isinstance(exc, KeyboardInterrupt)
            self.cancel()
            self._set_status("cancelled" if interrupted else "failed",
                             None if interrupted else f"{type(exc).__name__}: {exc}")
            raise
        finally:
            with self._lock:
                pool, self._pool = self._pool, None
            if pool is not None:
                pool.close()
            if ray_started:
                import ray

                ray.shutdown()
        self._set_status("cancelled" if self.cancelled else "done")
        if not self.cancelled:
            self._update(phase="done")
        self._summary = summarize_search(self.store, self.search_id)
        return self._summary

    def _start_ray(self) -> bool:
        """Start (or join) Ray once for the whole search: each trial's RayExecutor then uses it."""
        if not self.ray_address:
            return False
        import ray

        if ray.is_initialized():
            return False
        if self.ray_address == "local":
            ray.init(num_cpus=self.workers, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=self.ray_address, log_to_driver=False)
        return True

    def _set_status(self, status: str, error: str | None = None) -> None:
        with self.store.session() as session:
            records.set_search_status(
                session=session, search_id=self.search_id, status=status, error=error,
                workers=self.workers if status == "running" else None,
                executor=(f"ray:{self.ray_address}" if self.ray_address else "local")
                if status == "running" else None)
        self._update(status=status)

    # --- one episode --------------------------------------------------------------------------

    def _spec(self, number: int, params: Mapping[str, Any], seed: int) -> ScenarioSpec:
        return scenario_for(self.space, params, seed=seed,
                            name=trial_name(self.space.space.name, self.search_id, number),
                            description=self._description)

    def _run_trial(self, number: int, kind: str, parent: int | None, params: Mapping[str, Any],
                   seed: int) -> TrialResult:
        """Run trial ``number`` as a batch of one run (resuming its batch if it has one) and
        record it; its result."""
        from crossroads.evaluation.batch import BatchRunner, create_batch_for

        if self.cancelled:
            return TrialResult(number, "cancelled", None)
        spec = self._spec(number, params, seed)
        previous = self._stored.get(number)
        batch_id = previous.batch_id if previous is not None else None
        if batch_id is not None:
            with self.store.session() as session:
                ran = crud.get_episode(session=session, batch_id=batch_id, run_index=0)
            if ran is not None:  # recorded, but the trial was not: a fresh batch for its figures
                batch_id = None
        if batch_id is None:
            batch_id = create_batch_for(self.store, spec=spec, policy=self.policy_ref, runs=1,
                                        traces="failed", base_dir=self.failures_dir,
                                        warnings=self._warnings)
        with self.store.session() as session:
            records.start_trial(session=session, search_id=self.search_id, number=number,
                                kind=kind, parent=parent, params=params, seed=seed,
                                batch_id=batch_id)
        reports: list[Any] = []
        runner = BatchRunner(self.store, batch_id, data_dir=self.data_dir,
                             executor=self._executor_for_trial(),
                             on_progress=lambda _d, _t, last: reports.append(last) if last else None)
        with self._lock:
            self._active.add(runner)
        try:
            runner.run()
        finally:
            with self._lock:
                self._active.discard(runner)
        if not reports:  # cancelled before its episode was recorded: run again on resume
            return TrialResult(number, "cancelled", None)
        report = reports[-1]
        result = report.result
        outcome = report.outcome
        if result is None:
            result = {"outcome": "error", "detail": (report.error or "").splitlines()[0][:500]}
        value = objective(result, self.space.failures)
        with self.store.session() as session:
            records.finish_trial(session=session, search_id=self.search_id, number=number,
                                 outcome=outcome, objective=value, result=result)
        trial = TrialResult(number, outcome, value, result)
        self._count_trial(kind, trial)
        return trial

    def _executor_for_trial(self) -> Executor:
        """Where a trial's episode runs: the search's long-lived workers (started with the first
        trial), or, with ``executor="batch"``, Ray or where there is no fork, a fresh batch worker."""
        from crossroads.evaluation.batch import make_executor

        if self.executor != "pool" or self.ray_address or not FORK_EPISODES:
            return make_executor(workers=1, ray_address=self.ray_address)
        with self._lock:
            if self._pool is None:
                self._pool = TrialPool(self.policy_ref, self.workers)
            return PoolExecutor(self._pool)

    def _in_threads(self, task: Callable[[Any], Any], jobs: list[Any], what: str) -> list[Any]:
        """``task`` of every job, up to ``workers`` at once; an exception here (Ctrl-C) or in a
        task cancels the others' episodes at once rather than waiting for them."""
        with ThreadPoolExecutor(max_workers=min(self.workers, len(jobs)),
                                thread_name_prefix=f"crossroads-{what}-{self.search_id}") as pool:
            futures = [pool.submit(task, job) for job in jobs]
            try:
                return [f.result() for f in futures]
            except BaseException:
                self.cancel()
                raise

    # --- the search phase ---------------------------------------------------------------------

    def _search_phase(self) -> None:
        """Propose and run the search's trials. Trial ``n`` is proposed once trials 0 … n − L
        (L: the search's ``generation``) have been told, before trial n − L + 1 is, so it sees
        exactly those results, with trials n − L + 1 … n − 1 pending (TPE's constant liar), and a
        sampler seeded from the search's seed and ``n``: the same points whatever the workers and
        the episodes' durations. Up to ``workers`` trials run at once; a free worker takes the next
        proposed trial without waiting for the rest of its "generation"."""
        import optuna
        from optuna.trial import TrialState

        pool = seed_pool(self.space, self.seed)
        distributions = _distributions(self.space, pool)
        study = optuna.create_study(direction="minimize", sampler=make_sampler(self.sampler, 0))
        lag = self.generation
        asked: dict[int, Any] = {}
        finished: dict[int, float | None] = {}  # objectives not yet told
        to_run: deque[tuple[int, str, int | None, dict[str, Any], int]] = deque()
        failing = 0  # failures among the trials told

        def ask(number: int) -> None:
            study.sampler = make_sampler(self.sampler, trial_sampler_seed(self.seed, number), failing)
            trial = study.ask(distributions)
            params = {p.path: p.cast(trial.params[p.path]) for p in self.space.parameters}
            seed = (draw_seed(self.space, self.seed, number) if pool is None
                    else int(trial.params[SEED_KEY]))
            row = self._stored.get(number)
            if row is not None and (row.seed != seed or not _same_params(row.params, params)):
                raise SearchError(
                    f"search {self.search_id}: trial {number} was stored with {row.params}, seed "
                    f"{row.seed}, the sampler now proposes {params}, seed {seed} (another optuna or "
                    "Crossroads version?); start a new search")
            asked[number] = trial
            if row is not None and row.outcome is not None:  # resumed: told again, not run
                finished[number] = row.objective
            else:
                to_run.append((number, "search", None, params, seed))

        for number in range(min(lag, self.budget)):
            ask(number)
        told = 0
        with ThreadPoolExecutor(max_workers=self.workers,
                                thread_name_prefix=f"crossroads-search-{self.search_id}") as threads:
            running: dict[Future[TrialResult], int] = {}
            try:
                while told < self.budget and not self.cancelled:
                    if told in finished:
                        value = finished.pop(told)
                        if value is None:
                            study.tell(asked.pop(told), state=TrialState.FAIL)
                        else:
                            study.tell(asked.pop(told), value)
                            failing += value == FAILURE_VALUE
                        if told + lag < self.budget:
                            ask(told + lag)
                        told += 1
                        continue
                    while to_run and len(running) < self.workers:
                        job = to_run.popleft()
                        running[threads.submit(self._run_trial, *job)] = job[0]
                    done, _ = wait(running, return_when=FIRST_COMPLETED)
                    for future in done:
                        number = running.pop(future)
                        result = future.result()
                        if result.outcome == "cancelled":
                            return
                        finished[number] = result.objective
            except BaseException:
                self.cancel()  # the trials in flight stop at once rather than run to the end
                raise

    # --- the shrink phase ---------------------------------------------------------------------

    def _failing_trials(self) -> list[SearchTrial]:
        """The distinct failing search trials, by number (a repeat of the same scenario and seed
        is shrunk once)."""
        with self.store.session() as session:
            rows = records.trials(session=session, search_id=self.search_id, kind="search")
        seen: set[str] = set()
        out = []
        for row in rows:
            if row.objective != FAILURE_VALUE:
                continue
            key = distinct_key(self._spec(row.number, row.params, row.seed))
            if key not in seen:
                seen.add(key)
                out.append(row)
        return out

    def _shrink_phase(self) -> None:
        failing = self._failing_trials()
        self._update(phase="shrink", to_shrink=len(failing))
        with self.store.session() as session:
            self._stored = {t.number: t for t in records.trials(session=session, search_id=self.search_id)}
            recorded = {f.trial_number for f in records.failures(session=session, search_id=self.search_id)}
        jobs = [(k, row) for k, row in enumerate(failing) if row.number not in recorded]
        if not jobs:
            return
        self._in_threads(lambda job: self._shrink_one(*job), jobs, "shrink")

    def _shrink_one(self, index: int, failure: SearchTrial) -> None:
        """Shrink one failing trial (its steps numbered from ``budget + index·shrink_steps``) and
        put the minimal scenario into the failures collection."""
        assert failure.outcome is not None
        shrunk = self.shrink_limit is None or index < self.shrink_limit  # the rest: kept as found
        shrinker = Shrinker(self.space.parameters, failure.params, self.space.nominal_values(),
                            failure.outcome, max_steps=self.shrink_steps if shrunk else 0)
        first = self.budget + index * self.shrink_steps
        minimal = failure.number
        step = 0
        while (candidate := shrinker.candidate()) is not None:
            if self.cancelled:
                return
            number = first + step
            row = self._stored.get(number)
            if row is not None and row.outcome is not None:
                if not _same_params(row.params, candidate.params) or row.parent != failure.number:
                    raise SearchError(f"search {self.search_id}: shrinking trial {number} was "
                                      f"stored for other values; start a new search")
                outcome = row.outcome
            else:
                result = self._run_trial(number, "shrink", failure.number, candidate.params,
                                         failure.seed)
                if result.outcome == "cancelled":
                    return
                outcome = result.outcome
            shrinker.tell(outcome)
            if outcome == failure.outcome:
                minimal = number
            step += 1
        self._store_failure(failure, minimal, shrinker.current, shrunk=shrunk)

    def _store_failure(self, failure: SearchTrial, minimal: int, params: Mapping[str, Any], *,
                       shrunk: bool) -> None:
        cast = {p.path: p.cast(params[p.path]) for p in self.space.parameters}
        spec = self._spec(minimal, cast, failure.seed)
        distance = self.space.distance(cast)
        moved = self.space.off_nominal(cast)
        header = [
            f"A failure found by search {self.search_id} ({self.space.space.name}) for policy "
            f"{self.policy_ref}: {failure.outcome}.",
            (f"Shrunk from trial {failure.number} (minimal: trial {minimal})" if shrunk else
             f"Trial {failure.number}, kept as found (beyond the search's shrink limit)")
            + f"; distance from nominal {distance:g} (in parameter ranges); off nominal: "
            f"{', '.join(moved) or 'nothing'}.",
            f"Replay: crossroads evaluate {spec.name}.yaml --policy {self.policy_ref}",
        ]
        path = write_failure(self.failures_dir, spec, header=header)
        with self.store.session() as session:
            records.record_failure(session=session, search_id=self.search_id,
                                   trial_number=failure.number, minimal_number=minimal,
                                   outcome=failure.outcome, params=cast, seed=failure.seed,
                                   spec=spec.model_dump(mode="json"), content_hash=distinct_key(spec),
                                   distance=distance, off_nominal=moved, yaml_path=str(path))
        with self._lock:
            self._progress = replace(self._progress, failures=self._progress.failures + 1)
            progress = self._progress
        if self.on_progress is not None:
            self.on_progress(progress)


def summarize_search(store: Store, search_id: int) -> dict[str, Any]:
    """A stored search's figures: episodes, failing episodes, failures (distinct, by outcome and by
    which parameters they still need), best objective, and each failure (JSON-ready)."""
    with store.session() as session:
        search = records.get_search(session=session, search_id=search_id)
        if search is None:
            raise SearchError(f"no search {search_id} in {store.url}")
        rows = records.trials(session=session, search_id=search_id)
        found = records.failures(session=session, search_id=search_id)
        searched = [t for t in rows if t.kind == "search" and t.outcome is not None]
        shrunk = [t for t in rows if t.kind == "shrink" and t.outcome is not None]
        objectives = [t.objective for t in searched if t.objective is not None]
        outcomes: dict[str, int] = {}
        for t in searched:
            outcomes[str(t.outcome)] = outcomes.get(str(t.outcome), 0) + 1
        distinct = {f.content_hash for f in found}
        modes = {(f.outcome, tuple(f.off_nominal)) for f in found}
        return {
            "search_id": search.id, "name": search.name, "policy": search.policy.ref,
            "status": search.status, "sampler": search.sampler, "seed": search.seed,
            "budget": search.budget, "generation": search.generation,
            "searched": len(searched), "shrink_episodes": len(shrunk),
            "outcomes": outcomes,
            "failing": sum(t.objective == FAILURE_VALUE for t in searched),
            "failures": len(found), "distinct_failures": len(distinct),
            "failure_modes": len(modes),
            "best_objective": min(objectives) if objectives else None,
            "failures_dir": search.failures_dir, "error": search.error,
            "failure_list": [failure_json(f) for f in found],
        }


def failure_json(row: Any) -> dict[str, Any]:
    return {"id": row.id, "trial": row.trial_number, "minimal_trial": row.minimal_number,
            "outcome": row.outcome, "params": row.params, "seed": row.seed,
            "distance": row.distance, "off_nominal": row.off_nominal, "yaml_path": row.yaml_path,
            "name": row.spec.get("name")}
