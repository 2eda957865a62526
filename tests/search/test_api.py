"""The studio's search routes: start a search from a scenario, follow it, its failures (playback,
scenario file, save as a regression scenario) and its report, against a temporary store."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from fastapi.testclient import TestClient

from crossroads.api.main import create_app
from crossroads.settings import Settings

pytestmark = pytest.mark.slow

SCENARIO: dict[str, Any] = {
    "version": 1, "name": "api-red", "intersection": "a_single_lane", "task": "left",
    "traffic": {"vehicles_per_hour": 100, "cyclists_per_hour": 0, "pedestrians_per_hour": 0},
    "warmup_s": 5.0, "timeout_s": 10.0, "runs": 1, "seed": 1,
}
# the ego 3-6 m before the line at 9-10 m/s on the cross street's green: a red-light run
SPACE: dict[str, Any] = {
    "version": 1, "name": "api-red",
    "parameters": [{"path": "lights.phase", "choices": [4]},
                   {"path": "ego.start_distance_m", "low": 3.0, "high": 6.0},
                   {"path": "ego.start_speed_mps", "low": 9.0, "high": 10.0}],
}


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    settings = Settings(data_dir=tmp_path_factory.mktemp("search-api"), max_batch_workers=2)
    with TestClient(create_app(settings), base_url="http://127.0.0.1") as test_client:
        yield test_client


def _wait_done(client: TestClient, search_id: int, timeout_s: float = 300.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while True:
        body = client.get(f"/api/searches/{search_id}").json()
        if body["status"] in ("done", "failed", "cancelled") and body["progress"] is None:
            return body
        assert time.monotonic() < deadline, body
        time.sleep(0.2)


def test_a_search_from_the_studio_finds_a_failure_to_play_back_and_save(client: TestClient) -> None:
    started = client.post("/api/searches", json={
        "policy": "rule", "space": {**SPACE, "scenario": SCENARIO}, "budget": 1, "workers": 1,
        "shrink_steps": 2, "seed": 2})
    assert started.status_code == 202, started.text
    search_id = started.json()["id"]
    body = _wait_done(client, search_id)
    assert body["status"] == "done" and body["searched"] == 1 and body["failures"] == 1, body
    assert body["best_objective"] == -1.0
    [failure] = client.get(f"/api/searches/{search_id}/failures").json()
    assert failure["outcome"] == "red_light" and failure["playback"] == f"/api/playback/{failure['batch_id']}/0"
    assert failure["distance"] > 0 and "lights.phase" in failure["off_nominal"]
    trials = client.get(f"/api/searches/{search_id}/trials").json()
    assert [t["kind"] for t in trials] == ["search"] + ["shrink"] * (len(trials) - 1)
    text = client.get(f"/api/searches/{search_id}/failures/{failure['id']}/scenario.yaml").text
    spec = yaml.safe_load(text)
    assert spec["name"] == failure["name"] and spec["runs"] == 1 and spec["seed"] == failure["seed"]
    saved = client.post(f"/api/searches/{search_id}/failures/{failure['id']}/save")
    assert saved.status_code == 201
    again = client.post(f"/api/searches/{search_id}/failures/{failure['id']}/save")
    assert again.json()["scenario_id"] == saved.json()["scenario_id"]  # one scenario, however often
    stored = client.get(f"/api/scenarios/{saved.json()['scenario_id']}").json()
    assert stored["name"] == failure["name"]
    report = client.get(f"/api/searches/{search_id}/report")
    assert report.status_code == 200 and "data:image/png;base64," in report.text
    assert client.post(f"/api/searches/{search_id}/cancel").status_code == 409  # not running
    assert any(s["search_id"] == search_id for s in client.get("/api/searches").json())


def test_a_bad_search_is_refused_naming_the_field(client: TestClient, tmp_path: Path) -> None:
    def fields(response: Any) -> list[tuple[Any, ...]]:
        assert response.status_code == 422, response.text
        return [tuple(e["loc"]) for e in response.json()["detail"]]

    bad_range = {**SPACE, "scenario": SCENARIO,
                 "parameters": [{"path": "ego.start_distance_m", "low": 9.0, "high": 3.0}]}
    assert ("body", "space", "parameters", 0, "high") in fields(
        client.post("/api/searches", json={"policy": "rule", "space": bad_range}))
    a_path = {**SPACE, "scenario": "/etc/passwd"}
    assert ("body", "space", "scenario") in fields(client.post("/api/searches", json={"policy": "rule", "space": a_path}))
    no_phase = {**SPACE, "scenario": SCENARIO, "parameters": [{"path": "lights.phase", "choices": [40]}]}
    assert ("body", "space", "parameters", 0) in fields(
        client.post("/api/searches", json={"policy": "rule", "space": no_phase}))
    assert ("body", "policy") in fields(
        client.post("/api/searches", json={"policy": "nobody", "space": {**SPACE, "scenario": SCENARIO}}))
    assert client.get("/api/searches/999999").status_code == 404
    assert client.get("/api/searches/1/failures/999999/scenario.yaml").status_code == 404
