"""The batch queue of the API: at most ``max_concurrent_batches`` run at once, the others wait in
order and start as slots free; a waiting batch cancels at once; a shutdown marks the stopped
batches ``interrupted``; and at startup the API resumes the batches a previous process left queued,
running or interrupted, without running or counting any episode twice."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from crossroads.api.jobs import JobRegistry
from crossroads.api.main import create_app
from crossroads.evaluation.batch import Progress
from crossroads.scenario.spec import run_seeds, validate_scenario
from crossroads.settings import Settings
from crossroads.store import Store, crud, open_store

from .conftest import LOCAL_URL, TINY_SCENARIO, _wait_for  # noqa: TID252

WAIT_S = 10.0  # [s] for a fake runner's thread to get somewhere


class FakeRunner:
    """Stands in for a BatchRunner: marks the batch running, then waits to be released or
    cancelled and records the end like the real one (``cancelled`` on cancel)."""

    def __init__(self, store: Store, batch_id: int) -> None:
        self.store, self.batch_id = store, batch_id
        self.started, self.release, self._cancel = threading.Event(), threading.Event(), threading.Event()
        self.cancelled_at_end = False

    @property
    def progress(self) -> Progress:
        return Progress(self.batch_id, "running", 0, 1)

    def _status(self, status: str) -> None:
        with self.store.session() as session:
            crud.set_batch_status(session=session, batch_id=self.batch_id, status=status)

    def run(self) -> Any:
        self._status("running")
        self.started.set()
        while not (self.release.is_set() or self._cancel.is_set()):
            time.sleep(0.01)
        self.cancelled_at_end = self._cancel.is_set()
        self._status("cancelled" if self.cancelled_at_end else "done")

    def cancel(self) -> None:
        self._cancel.set()


@pytest.fixture
def store(tmp_path: Path) -> Iterator[Store]:
    with open_store(f"sqlite:///{tmp_path / 'jobs.db'}") as opened:
        yield opened


def _batches(store: Store, n: int, runs: int = 1, status: str = "queued") -> list[int]:
    spec = validate_scenario(TINY_SCENARIO, check_references=False)
    ids = []
    with store.session() as session:
        scenario = crud.get_or_create_scenario(session=session, spec=spec)
        policy = crud.get_or_create_policy(session=session, ref="rule")
        for _ in range(n):
            batch = crud.create_batch(session=session, scenario=scenario, policy=policy, runs=runs)
            if status != "queued":
                crud.set_batch_status(session=session, batch_id=batch.id, status=status)
            ids.append(batch.id)
    return ids


def _status(store: Store, batch_id: int) -> str:
    with store.session() as session:
        batch = crud.get_batch(session=session, batch_id=batch_id)
        assert batch is not None
        return batch.status


def _until(condition: Any, timeout_s: float = WAIT_S) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def test_the_cap_queues_in_order_and_slots_free_up(store: Store, tmp_path: Path) -> None:
    runners: dict[int, FakeRunner] = {}
    jobs = JobRegistry(store, data_dir=tmp_path, max_running=2,
                       runner_factory=lambda b, _w: runners.setdefault(b, FakeRunner(store, b)))
    a, b, c, d = _batches(store, 4)
    for batch_id in (a, b, c, d):
        jobs.submit(batch_id)
    _until(lambda: a in runners and b in runners and runners[a].started.is_set()
           and runners[b].started.is_set())
    assert jobs.running() == [a, b] and jobs.queued() == [c, d]
    assert (jobs.queue_position(c), jobs.queue_position(d), jobs.queue_position(a)) == (1, 2, None)
    assert _status(store, c) == "queued" and c not in runners, "a waiting batch has no runner yet"

    assert jobs.cancel(d) == "dequeued" and jobs.queued() == [c], "a waiting batch leaves at once"
    runners[a].release.set()  # a ends: its slot goes to c, the next in line
    _until(lambda: c in runners and runners[c].started.is_set())
    assert jobs.running() == [b, c] and jobs.queued() == []
    assert _status(store, a) == "done" and d not in runners

    assert jobs.cancel(b) == "cancelling"
    # the runner records "cancelled" before its thread lets the registry go: wait for both, or the
    # registry still holds b (a race seen once in CI on a fresh clone)
    _until(lambda: _status(store, b) == "cancelled" and b not in jobs.running())
    assert jobs.cancel(b) is None and jobs.cancel(d) is None
    runners[c].release.set()
    _until(lambda: jobs.running() == [])
    assert _status(store, c) == "done"


def test_shutdown_marks_stopped_batches_interrupted(store: Store, tmp_path: Path) -> None:
    runners: dict[int, FakeRunner] = {}
    jobs = JobRegistry(store, data_dir=tmp_path, max_running=1,
                       runner_factory=lambda b, _w: runners.setdefault(b, FakeRunner(store, b)))
    a, b = _batches(store, 2)
    for batch_id in (a, b):
        jobs.submit(batch_id)
    _until(lambda: a in runners and runners[a].started.is_set())
    jobs.shutdown(timeout_s=WAIT_S)
    assert runners[a].cancelled_at_end, "the shutdown stopped the running batch"
    assert (_status(store, a), _status(store, b)) == ("interrupted", "interrupted"), \
        "both said interrupted (the next start goes on with them), neither running nor queued forever"
    with store.session() as session:
        stopped = crud.get_batch(session=session, batch_id=a)
        assert stopped is not None and stopped.error is not None and "server stopped" in stopped.error
        assert stopped.finished_at is None
    jobs.submit(b)  # a closing registry starts nothing
    assert b not in runners


def test_a_batch_ended_meanwhile_is_not_run_again(store: Store, tmp_path: Path) -> None:
    runners: dict[int, FakeRunner] = {}
    jobs = JobRegistry(store, data_dir=tmp_path, max_running=1,
                       runner_factory=lambda b, _w: runners.setdefault(b, FakeRunner(store, b)))
    (done,) = _batches(store, 1, status="cancelled")
    jobs.submit(done)
    _until(lambda: jobs.running() == [])
    assert not runners[done].started.is_set() and _status(store, done) == "cancelled"


def test_the_api_queues_beyond_the_cap(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path, max_concurrent_batches=1)
    with TestClient(create_app(settings), base_url=LOCAL_URL) as client:
        long = client.post("/api/batches", json={"scenario": {**TINY_SCENARIO, "name": "cap-long"},
                                                 "runs": 40, "workers": 1, "traces": "none"})
        assert long.status_code == 202 and long.json()["queue_position"] is None
        first = long.json()["id"]
        _wait_for(client, first, ("running",), timeout_s=60)
        short = client.post("/api/batches", json={"scenario": {**TINY_SCENARIO, "name": "cap-short"},
                                                  "runs": 1, "workers": 1, "traces": "none"})
        dropped = client.post("/api/batches", json={"scenario": {**TINY_SCENARIO, "name": "cap-drop"},
                                                    "runs": 1, "workers": 1, "traces": "none"})
        assert short.status_code == dropped.status_code == 202
        second, third = short.json()["id"], dropped.json()["id"]
        assert (short.json()["status"], short.json()["queue_position"]) == ("queued", 1)
        body = client.get(f"/api/batches/{third}").json()
        assert (body["status"], body["queue_position"]) == ("queued", 2)

        cancelled = client.post(f"/api/batches/{third}/cancel")  # waiting: cancelled at once
        assert cancelled.status_code == 202 and cancelled.json()["status"] == "cancelled"
        assert client.get(f"/api/batches/{second}").json()["queue_position"] == 1

        assert client.post(f"/api/batches/{first}/cancel").json()["status"] == "cancelling"
        assert _wait_for(client, first, ("cancelled",), timeout_s=60)["status"] == "cancelled"
        ended = _wait_for(client, second, ("done", "failed", "cancelled"))
        assert ended["status"] == "done" and ended["progress"]["done"] == 1
        third_body = client.get(f"/api/batches/{third}").json()
        assert third_body["status"] == "cancelled" and third_body["progress"]["done"] == 0


def test_startup_resumes_unfinished_batches_without_running_an_episode_twice(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path, max_concurrent_batches=1)
    spec = validate_scenario({**TINY_SCENARIO, "name": "resume-me", "runs": 3}, check_references=False)
    seeds = run_seeds(spec, 3)
    # What a process that stopped mid-batch leaves: a running batch with two runs recorded, a
    # queued one never started, and a cancelled one that must stay as it is.
    with open_store(settings.database_url) as store:
        with store.session() as session:
            scenario = crud.get_or_create_scenario(session=session, spec=spec)
            policy = crud.get_or_create_policy(session=session, ref="rule")
            made = [crud.create_batch(session=session, scenario=scenario, policy=policy, runs=n,
                                      traces="none", workers=1) for n in (3, 1, 2)]
            interrupted, waiting, cancelled = (b.id for b in made)
            crud.set_batch_status(session=session, batch_id=interrupted, status="running")
            crud.set_batch_status(session=session, batch_id=cancelled, status="cancelled")
            for i in (0, 1):
                crud.record_episode(session=session, batch_id=interrupted, run_index=i, seed=seeds[i],
                                    result={"outcome": "passed", "travel_time_s": 4.0, "steps": 40,
                                            "time_s": 4.0, "min_distance_m": 9.0,
                                            "detail": "recorded before the restart", "events": []})

    with TestClient(create_app(settings), base_url=LOCAL_URL) as client:
        for batch_id, runs in ((interrupted, 3), (waiting, 1)):
            body = _wait_for(client, batch_id, ("done", "failed", "cancelled"))
            assert body["status"] == "done", body
            assert body["progress"]["done"] == body["summary"]["recorded"] == runs
        episodes = client.get(f"/api/batches/{interrupted}/episodes").json()
        assert [e["run_index"] for e in episodes] == [0, 1, 2], "each run exactly once"
        assert [e["seed"] for e in episodes] == seeds
        assert [e["detail"] for e in episodes[:2]] == ["recorded before the restart"] * 2, \
            "the runs recorded before were not run again"
        assert episodes[2]["detail"] != "recorded before the restart"
        body = client.get(f"/api/batches/{cancelled}").json()
        assert body["status"] == "cancelled" and body["progress"]["done"] == 0


def test_resume_can_be_turned_off(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path, resume_batches=False)
    with open_store(settings.database_url) as store:
        (left,) = _batches(store, 1, status="running")
    with TestClient(create_app(settings), base_url=LOCAL_URL) as client:
        time.sleep(0.5)
        body = client.get(f"/api/batches/{left}").json()
        assert body["status"] == "running" and body["progress"]["done"] == 0
        assert client.app.state.jobs.running() == []


def test_a_cancel_is_kept_across_a_restart(tmp_path: Path) -> None:
    """A cancel asked for before the server stopped (killed before the runner could record it,
    or before the batch ever started) ends the batch at the next start: nothing is resumed."""
    settings = Settings(data_dir=tmp_path, max_concurrent_batches=1)
    with open_store(settings.database_url) as store:
        running, waiting = _batches(store, 1, status="running") + _batches(store, 1)
        (untouched,) = _batches(store, 1, runs=1)
        with store.session() as session:
            for batch_id in (running, waiting):
                crud.request_cancel(session=session, batch_id=batch_id)
            assert [b.id for b in crud.unfinished_batches(session=session)] == [untouched]
    with TestClient(create_app(settings), base_url=LOCAL_URL) as client:
        for batch_id in (running, waiting):
            body = client.get(f"/api/batches/{batch_id}").json()
            assert (body["status"], body["cancel_requested"], body["progress"]["done"]) == ("cancelled", True, 0)
            assert body["finished_at"]
        assert _wait_for(client, untouched, ("done", "failed", "cancelled"))["status"] == "done"


def test_a_cancel_while_starting_stops_the_batch_for_good(tmp_path: Path) -> None:
    """A cancel that comes while the batch is still being set up (its runner planning, status
    still queued) ends it cancelled, and a restart does not bring it back."""
    settings = Settings(data_dir=tmp_path, max_concurrent_batches=1)
    with TestClient(create_app(settings), base_url=LOCAL_URL) as client:
        started = client.post("/api/batches", json={"scenario": {**TINY_SCENARIO, "name": "cancel-early"},
                                                    "runs": 40, "workers": 1, "traces": "none"})
        batch_id = started.json()["id"]
        assert started.json()["status"] == "queued"
        cancel = client.post(f"/api/batches/{batch_id}/cancel")
        assert cancel.status_code == 202 and cancel.json()["status"] in ("cancelling", "cancelled")
        body = _wait_for(client, batch_id, ("cancelled", "done", "failed"), timeout_s=60)
        assert body["status"] == "cancelled" and body["cancel_requested"] and body["progress"]["done"] < 40
        done = body["progress"]["done"]
    with TestClient(create_app(settings), base_url=LOCAL_URL) as client:
        time.sleep(0.5)
        body = client.get(f"/api/batches/{batch_id}").json()
        assert (body["status"], body["progress"]["done"]) == ("cancelled", done)
        assert client.app.state.jobs.running() == []
        assert client.post(f"/api/batches/{batch_id}/cancel").status_code == 409


def test_an_episode_beyond_the_wall_clock_limit_is_an_error(tmp_path: Path) -> None:
    """settings.episode_wall_limit_s: an episode still running after it is stopped (its worker
    killed) and recorded as an error; the batch goes on to its end."""
    settings = Settings(data_dir=tmp_path, episode_wall_limit_s=1.0)
    with TestClient(create_app(settings), base_url=LOCAL_URL) as client:
        # ten minutes of busy traffic before the ego enters: several seconds of wall-clock at least
        slow = {**TINY_SCENARIO, "name": "too-slow", "warmup_s": 600.0,
                "traffic": {"vehicles_per_hour": 800.0, "cyclists_per_hour": 100.0, "pedestrians_per_hour": 100.0}}
        started = client.post("/api/batches", json={"scenario": slow,
                                                    "runs": 2, "workers": 1, "traces": "none"})
        body = _wait_for(client, started.json()["id"], ("done", "failed", "cancelled"), timeout_s=60)
        assert body["status"] == "done" and body["progress"]["errors"] == 2, body
        episodes = client.get(f"/api/batches/{body['id']}/episodes").json()
        assert [e["outcome"] for e in episodes] == ["error", "error"]
        assert all(e["error_message"].startswith("wall-clock limit: the episode ran longer than 1 s")
                   for e in episodes), episodes
