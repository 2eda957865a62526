"""The search's long-lived workers (search/pool.py): a trial run there gives the episode a fresh
batch worker gives (what `crossroads evaluate` runs), whatever the worker ran before; a child that
dies, a cancel and a close leave the pool usable or gone, not stuck."""

from __future__ import annotations

import threading
import time
from dataclasses import replace
from pathlib import Path

import pytest
from support import REPO_ROOT

from crossroads.evaluation.executors import (
    FORK_EPISODES,
    EpisodeReport,
    EpisodeTask,
    ProcessExecutor,
    WorkerJob,
)
from crossroads.scenario.spec import load_scenario, run_seeds
from crossroads.search.pool import PoolExecutor, TrialPool

pytestmark = pytest.mark.skipif(not FORK_EPISODES, reason="the pool forks its episodes")

NOMINAL_LEFT = REPO_ROOT / "scenarios" / "nominal" / "c_three_lane-left.yaml"
# The seed whose SUMO traffic depends on the process's memory (tests/evaluation/test_executors.py,
# docs/tried/world.md): the episode the pool gives must be the one a fresh batch worker gives.
SENSITIVE_SEED = 2090914255


def job_for(path: Path, **changes: object) -> WorkerJob:
    spec = load_scenario(path).model_copy(update=changes)
    return WorkerJob(spec=spec.model_dump(mode="json"), base_dir=str(path.parent), policy_ref="rule",
                     traces="none")


def in_fresh_worker(job: WorkerJob, task: EpisodeTask) -> EpisodeReport:
    """``task`` as `crossroads evaluate` runs it: a batch worker process started for it."""
    reports: list[EpisodeReport] = []
    ProcessExecutor(workers=1).run(job, [task], reports.append, threading.Event())
    (report,) = reports
    return report


@pytest.mark.slow
def test_a_trial_in_the_pool_is_the_episode_a_fresh_batch_worker_gives() -> None:
    """The sensitive seed in the pool first, and again after trials of other scenarios (other
    traffic, another intersection) on the same worker: each time the report of a fresh batch
    worker, field for field (outcome, steps, times, near-miss figures, events)."""
    nominal = job_for(NOMINAL_LEFT)
    target = EpisodeTask(0, SENSITIVE_SEED)
    alone = in_fresh_worker(nominal, target)
    assert alone.result is not None
    seeds = run_seeds(load_scenario(NOMINAL_LEFT), 3)
    others = [
        (job_for(NOMINAL_LEFT, traffic=load_scenario(NOMINAL_LEFT).traffic.model_copy(
            update={"vehicles_per_hour": 700.0}), timeout_s=20.0), EpisodeTask(1, seeds[1])),
        (job_for(REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-left.yaml", timeout_s=20.0),
         EpisodeTask(2, seeds[2])),
    ]
    cancel = threading.Event()
    with TrialPool("rule", 1) as pool:
        first = pool.run(nominal, target, cancel)
        for job, task in others:
            other = pool.run(job, task, cancel)
            assert other is not None and other.result is not None
        after = pool.run(nominal, target, cancel)
        assert len(pool.worker_pids()) == 1  # one long-lived worker ran all four
    assert first is not None and after is not None
    assert first.result == alone.result and after.result == alone.result
    assert first.worker != after.worker  # each trial in its own forked child


def test_a_child_that_dies_is_an_error_report_and_the_worker_runs_the_next_trial() -> None:
    job = job_for(REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-left.yaml", warmup_s=2.0,
                  timeout_s=3.0)
    cancel = threading.Event()
    with TrialPool("rule", 1) as pool:
        (pid,) = pool.worker_pids()
        killed = pool.run(replace(job, faults={0: "kill"}), EpisodeTask(0, 5), cancel)
        assert killed is not None and killed.result is None and killed.error is not None
        assert killed.error.startswith("WorkerDied: episode process") and "SIGKILL" in killed.error
        after = pool.run(job, EpisodeTask(1, 5), cancel)
        assert after is not None and after.result is not None
        assert pool.worker_pids() == [pid]
        # an exception in the episode is its error report, as in a batch worker
        raised = pool.run(replace(job, faults={2: "raise"}), EpisodeTask(2, 5), cancel)
        assert raised is not None and raised.error is not None and "injected fault" in raised.error
    assert not _alive(pid)  # closed: the worker is gone


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] not in ("Z", "X")
    except OSError:
        return False


def test_cancel_drops_the_episode_and_a_new_worker_takes_the_next() -> None:
    nominal = REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-left.yaml"
    short = job_for(nominal, warmup_s=2.0, timeout_s=3.0)
    long = job_for(nominal, warmup_s=600.0, timeout_s=3600.0)  # 6 000 warm-up steps before the ego
    with TrialPool("rule", 1) as pool:
        (first_pid,) = pool.worker_pids()
        warm = pool.run(short, EpisodeTask(0, 7), threading.Event())
        assert warm is not None and warm.result is not None
        cancel = threading.Event()
        threading.Timer(0.5, cancel.set).start()
        started = time.monotonic()
        assert pool.run(long, EpisodeTask(1, 7), cancel) is None
        assert time.monotonic() - started < 10.0
        assert not _alive(first_pid)  # killed with its episode
        reports: list[EpisodeReport] = []
        PoolExecutor(pool).run(short, [EpisodeTask(2, 7), EpisodeTask(3, 8)], reports.append,
                               threading.Event())
        assert [r.run_index for r in reports] == [2, 3] and all(r.result is not None for r in reports)
        pids = pool.worker_pids()
        assert pids and pids != [first_pid]
    assert not any(_alive(pid) for pid in pids)
