"""Episode workers (evaluation/executors.py): an episode's result does not depend on what its
worker ran before."""

from __future__ import annotations

import threading
from dataclasses import replace
from pathlib import Path

import pytest
from support import REPO_ROOT

from crossroads.evaluation.executors import (
    FORK_EPISODES,
    EpisodeReport,
    EpisodeTask,
    EpisodeWorker,
    ProcessExecutor,
    WorkerJob,
)
from crossroads.scenario.spec import load_scenario, run_seeds

NOMINAL_LEFT = REPO_ROOT / "scenarios" / "nominal" / "c_three_lane-left.yaml"
# A seed whose SUMO traffic depends on the process's memory: with the rule controller, run first
# it times out; run after the first three seeds in the same process it passed (measured:
# docs/tried/world.md, "Same seed, same episode"). Whether it flips on another host is not ours to say; that the
# forked worker gives the same report either way is.
SENSITIVE_SEED = 2090914255


def nominal_job() -> WorkerJob:
    spec = load_scenario(NOMINAL_LEFT)
    return WorkerJob(spec=spec.model_dump(mode="json"), base_dir=str(Path(NOMINAL_LEFT).parent),
                     policy_ref="rule", traces="none")


def run_tasks(tasks: list[EpisodeTask], job: WorkerJob | None = None) -> list[EpisodeReport]:
    """``tasks`` through one local worker process, in order; their reports in the same order."""
    reports: list[EpisodeReport] = []
    ProcessExecutor(workers=1).run(job or nominal_job(), tasks, reports.append, threading.Event())
    return reports


@pytest.mark.slow
@pytest.mark.skipif(not FORK_EPISODES, reason="episodes run in a forked child only where fork exists")
def test_an_episode_ends_the_same_whatever_its_worker_ran_before() -> None:
    """The sensitive seed run first by a worker, then by another worker after each of six different
    histories of other episodes: the same result every time. Unforked (``FORK_EPISODES`` set False
    in the module) this failed here: not all six equalled the first."""
    seeds = run_seeds(load_scenario(NOMINAL_LEFT), 12)
    target = EpisodeTask(99, SENSITIVE_SEED)
    (first,) = run_tasks([target])
    assert first.result is not None
    tasks: list[EpisodeTask] = []
    for history in ([0], [1, 2], [3], [4, 5, 6], [7, 8], [9, 10, 11]):
        tasks += [EpisodeTask(i, seeds[i]) for i in history] + [target]
    reports = run_tasks(tasks)
    assert [r.run_index for r in reports] == [t.run_index for t in tasks]
    assert all(r.result is not None for r in reports)
    after = [r.result for r in reports if r.run_index == target.run_index]
    assert len(after) == 6 and all(result == first.result for result in after)  # outcome, steps, events, ...


@pytest.mark.skipif(not FORK_EPISODES, reason="episodes run in a forked child only where fork exists")
def test_a_child_that_dies_is_an_error_report_and_the_worker_goes_on() -> None:
    """A killed episode comes back as its run's error, and the same worker process runs the next."""
    seed = run_seeds(load_scenario(NOMINAL_LEFT), 1)[0]
    job = replace(nominal_job(), faults={0: "kill"})
    killed, after = run_tasks([EpisodeTask(0, seed), EpisodeTask(1, seed)], job)
    assert killed.result is None and killed.error is not None
    assert killed.error.startswith("WorkerDied: episode process") and "SIGKILL" in killed.error
    assert after.result is not None
    assert killed.error.split(" of ")[1].startswith(after.worker)  # the child's worker ran the next run too


def test_a_forked_episode_reports_as_an_unforked_one() -> None:
    """``EpisodeWorker.run_forked`` (Ray's actors) gives the report ``run`` gives in a fresh worker."""
    seed = run_seeds(load_scenario(NOMINAL_LEFT), 1)[0]
    forked = EpisodeWorker(nominal_job())
    here = EpisodeWorker(nominal_job())
    try:
        assert forked.run_forked(EpisodeTask(0, seed)).result == here.run(EpisodeTask(0, seed)).result
    finally:
        forked.close()
        here.close()


def _write_then_hang(marker: str, conn: object, scratch: str) -> None:
    """A worker process that writes a temporary file, says where, and never returns."""
    import tempfile
    import time

    from crossroads.evaluation.executors import adopt_scratch_dir

    adopt_scratch_dir(scratch)
    handle, path = tempfile.mkstemp(prefix=marker)
    conn.send(path)  # type: ignore[attr-defined]
    time.sleep(3600)


def test_a_killed_worker_leaves_no_temporary_files() -> None:
    """A worker killed mid-episode (a run past its wall-clock limit, a cancelled batch) cannot
    remove its World's files; its scratch directory goes with it."""
    import multiprocessing as mp

    from crossroads.evaluation.executors import WorkerProcess

    worker = WorkerProcess(mp.get_context("fork"), _write_then_hang, ("crossroads-test-",), "test-worker")
    path = Path(worker.conn.recv())
    assert path.exists() and path.parent == Path(worker.scratch)
    worker.stop(force=True)
    assert not worker.alive() and not Path(worker.scratch).exists()
