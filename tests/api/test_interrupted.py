"""Batches a stopped server leaves behind: the heartbeat of the API's registry, batches abandoned
by a killed server marked ``interrupted`` (never shown running forever), resuming one from the
API, and the progress's elapsed time, rate and ETA read from the store alone."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from crossroads.api.jobs import JobRegistry
from crossroads.api.main import create_app
from crossroads.evaluation.batch import Progress
from crossroads.settings import Settings
from crossroads.store import Store, crud, open_store
from crossroads.store.tables import utcnow

from .conftest import LOCAL_URL, TINY_SCENARIO, _wait_for  # noqa: TID252
from .test_jobs import _batches, _status, _until  # noqa: TID252


class IdleRunner:
    """Marks its batch running and waits to be cancelled (a batch that is always in hand)."""

    def __init__(self, store: Store, batch_id: int) -> None:
        self.store, self.batch_id, self._cancel = store, batch_id, threading.Event()

    @property
    def progress(self) -> Progress:
        return Progress(self.batch_id, "running", 0, 1)

    def run(self) -> Any:
        with self.store.session() as session:
            crud.set_batch_status(session=session, batch_id=self.batch_id, status="running")
        self._cancel.wait(30)
        with self.store.session() as session:
            crud.set_batch_status(session=session, batch_id=self.batch_id, status="cancelled")

    def cancel(self) -> None:
        self._cancel.set()


@pytest.fixture
def store(tmp_path: Path) -> Iterator[Store]:
    with open_store(f"sqlite:///{tmp_path / 'beats.db'}") as opened:
        yield opened


def _heartbeat(store: Store, batch_id: int) -> Any:
    with store.session() as session:
        batch = crud.get_batch(session=session, batch_id=batch_id)
        assert batch is not None
        return batch.heartbeat_at


def _stamp(store: Store, batch_id: int, age_s: float) -> None:
    with store.session() as session:
        batch = crud.get_batch(session=session, batch_id=batch_id)
        assert batch is not None
        batch.heartbeat_at = utcnow() - timedelta(seconds=age_s)
        session.commit()


def test_the_heartbeat_stamps_its_batches_and_marks_abandoned_ones(store: Store, tmp_path: Path) -> None:
    jobs = JobRegistry(store, data_dir=tmp_path, max_running=1, heartbeat_s=0.05, stale_after_s=0.5,
                       runner_factory=lambda b, _w: IdleRunner(store, b))
    mine, waiting = _batches(store, 2)
    abandoned, fresh, by_cli = _batches(store, 3, status="running")
    _stamp(store, abandoned, age_s=60)  # its server was killed a minute ago
    _stamp(store, fresh, age_s=0)  # another server, alive: it keeps stamping... or not
    jobs.submit(mine)
    jobs.submit(waiting)
    jobs.start_heartbeat()
    try:
        assert _status(store, abandoned) == "interrupted", "marked at once on start"
        first = _heartbeat(store, mine)
        assert first is not None and _heartbeat(store, waiting) is not None, "a waiting batch is in hand too"
        _until(lambda: _heartbeat(store, mine) != first)
        _until(lambda: _status(store, fresh) == "interrupted")  # nobody stamped it: stale after 0.5 s
        assert _status(store, mine) == "running" and _status(store, waiting) == "queued", \
            "this registry's own batches are never judged abandoned"
        assert _status(store, by_cli) == "running", "no heartbeat (crossroads evaluate): not judged"
        with store.session() as session:
            batch = crud.get_batch(session=session, batch_id=abandoned)
            assert batch is not None and batch.error is not None and "resume it" in batch.error
    finally:
        jobs.shutdown(timeout_s=10)
    assert _status(store, mine) == _status(store, waiting) == "interrupted"


def test_heartbeat_settings_are_checked(store: Store, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="heartbeat_s"):
        JobRegistry(store, data_dir=tmp_path, heartbeat_s=30, stale_after_s=30)


def test_an_abandoned_batch_shows_interrupted_and_resumes_from_the_api(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path, resume_batches=False)
    with open_store(settings.database_url) as store:
        (left,) = _batches(store, 1, runs=2, status="running")
        (waiting,) = _batches(store, 1, runs=1)
        (done,) = _batches(store, 1, status="done")
        for batch_id in (left, waiting):
            _stamp(store, batch_id, age_s=120)
    with TestClient(create_app(settings), base_url=LOCAL_URL) as client:
        for batch_id in (left, waiting):
            body = client.get(f"/api/batches/{batch_id}").json()
            assert body["status"] == "interrupted", body
            assert body["error"].startswith("interrupted: the server running it stopped")
            assert body["progress"]["eta_s"] is None
        listed = client.get("/api/batches", params={"status": "interrupted"})
        assert listed.status_code == 200 and {b["id"] for b in listed.json()} == {left, waiting}
        # the event stream of an interrupted batch ends at once (no runner goes on with it)
        with client.stream("GET", f"/api/batches/{left}/events") as stream:
            text = "".join(stream.iter_text())
        assert "event: end" in text and '"status":"interrupted"' in text

        refused = client.post(f"/api/batches/{done}/resume")
        assert refused.status_code == 409 and "only an interrupted batch" in refused.json()["detail"]
        assert client.post("/api/batches/999999/resume").status_code == 404

        resumed = client.post(f"/api/batches/{left}/resume")
        assert resumed.status_code == 202, resumed.text
        assert resumed.json()["status"] in ("queued", "running")
        body = _wait_for(client, left, ("done", "failed", "cancelled", "interrupted"))
        assert body["status"] == "done" and body["error"] is None, body
        p = body["progress"]
        assert p["done"] == p["since_start"] == 2
        assert p["elapsed_s"] is not None and p["elapsed_s"] >= 0
        assert p["rate_per_min"] is not None and p["rate_per_min"] > 0
        assert p["eta_s"] is None, "no ETA once ended"
        assert client.post(f"/api/batches/{left}/resume").status_code == 409
        # the other one stays interrupted until a user resumes it (resuming is off)
        assert client.get(f"/api/batches/{waiting}").json()["status"] == "interrupted"


def test_a_running_batch_has_an_eta(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path, max_concurrent_batches=1)
    with TestClient(create_app(settings), base_url=LOCAL_URL) as client:
        started = client.post("/api/batches", json={"scenario": {**TINY_SCENARIO, "name": "eta"},
                                                    "runs": 40, "workers": 1, "traces": "none"})
        batch_id = started.json()["id"]
        deadline = time.monotonic() + 120
        while True:
            body = client.get(f"/api/batches/{batch_id}").json()
            p = body["progress"]
            if body["status"] == "running" and p["since_start"] >= 1:
                break
            assert time.monotonic() < deadline and body["status"] in ("queued", "running"), body
            time.sleep(0.2)
        assert p["rate_per_min"] > 0 and p["eta_s"] is not None and p["eta_s"] > 0
        # the ETA is the runs left at the rate (both rounded)
        expected = (p["total"] - p["done"]) / p["rate_per_min"] * 60
        assert abs(p["eta_s"] - expected) <= max(2.0, 0.1 * expected), p
        assert client.post(f"/api/batches/{batch_id}/cancel").status_code == 202
        _wait_for(client, batch_id, ("cancelled",), timeout_s=60)
