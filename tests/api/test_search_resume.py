"""A failure search across a server restart: its live progress carries elapsed time, rate and ETA;
a shutdown stops it and records why (state ``interrupted``, not running forever); the next server
resumes it from the store on request, and refuses what cannot be resumed."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from crossroads.api.main import create_app
from crossroads.api.routes.searches import INTERRUPTED
from crossroads.search import records
from crossroads.settings import Settings
from crossroads.store import open_store

from .conftest import LOCAL_URL, TINY_SCENARIO  # noqa: TID252

pytestmark = pytest.mark.slow

SPACE: dict[str, Any] = {"version": 1, "name": "api-resume",
                         "parameters": [{"path": "ego.start_distance_m", "low": 20.0, "high": 40.0}]}


def _until(client: TestClient, search_id: int, test: Any, timeout_s: float = 180.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while True:
        body = client.get(f"/api/searches/{search_id}").json()
        if test(body):
            return body
        assert time.monotonic() < deadline, body
        time.sleep(0.2)


def test_a_search_stopped_by_a_shutdown_reads_interrupted_and_resumes(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path, max_batch_workers=1)
    with TestClient(create_app(settings), base_url=LOCAL_URL) as client:
        started = client.post("/api/searches", json={
            "policy": "rule", "space": {**SPACE, "scenario": TINY_SCENARIO}, "budget": 60, "workers": 1,
            "generation": 1, "shrink_steps": 0})
        assert started.status_code == 202, started.text
        search_id = started.json()["id"]
        body = _until(client, search_id, lambda b: b["progress"] and b["progress"]["searched"] >= 2)
        p = body["progress"]
        assert body["state"] == "running" and p["elapsed_s"] >= 0
        assert p["rate_per_min"] > 0 and p["eta_s"] > 0, p
        assert client.post(f"/api/searches/{search_id}/resume").status_code == 409  # running here
    # the shutdown stopped it: cancelled, with the reason, and read as interrupted
    with TestClient(create_app(settings), base_url=LOCAL_URL) as client:
        body = client.get(f"/api/searches/{search_id}").json()
        assert (body["status"], body["state"], body["error"], body["progress"]) == \
            ("cancelled", "interrupted", INTERRUPTED, None)
        searched = body["searched"]
        assert 2 <= searched < 60
        resumed = client.post(f"/api/searches/{search_id}/resume")
        assert resumed.status_code == 202, resumed.text
        body = _until(client, search_id, lambda b: b["progress"] and b["progress"]["searched"] > searched)
        assert body["state"] == "running" and body["progress"]["elapsed_s"] is not None
        assert client.post(f"/api/searches/{search_id}/cancel").status_code == 202
        body = _until(client, search_id, lambda b: b["progress"] is None)
        assert (body["status"], body["state"], body["error"]) == ("cancelled", "cancelled", None)
        assert body["searched"] > searched, "went on from the episodes recorded"

        # left running by a killed process: no runner here, so interrupted (and resumable)
        with open_store(settings.database_url) as store, store.session() as session:
            records.set_search_status(session=session, search_id=search_id, status="running")
        assert client.get(f"/api/searches/{search_id}").json()["state"] == "interrupted"
        with open_store(settings.database_url) as store, store.session() as session:
            records.set_search_status(session=session, search_id=search_id, status="done")
        refused = client.post(f"/api/searches/{search_id}/resume")
        assert refused.status_code == 409 and "only an interrupted or cancelled" in refused.json()["detail"]
        assert client.post("/api/searches/999999/resume").status_code == 404
