"""Bounded inputs: every numeric field of a scenario and a batch has a ceiling; ids beyond their
columns, NaN and infinities are 422s (never 500s); bodies have a size limit; every list is paged;
intersection names never reach the server's files."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from crossroads.api.params import TOTAL_HEADER

BIG_IDS = [2**31, 2**63 - 1, 2**63, 2**64 + 1, 10**30]


@pytest.mark.parametrize(("patch", "loc"), [
    ({"runs": 1_000_000_000_000}, ("runs",)),
    ({"runs": 10**30}, ("runs",)),
    ({"runs": 10_001}, ("runs",)),
    ({"warmup_s": 1e7}, ("warmup_s",)),
    ({"timeout_s": 3601.0}, ("timeout_s",)),
    ({"abnormal": {"overspeed": {"share": 0.1, "excess": 1e308}}}, ("abnormal", "overspeed", "excess")),
    ({"traffic": {"vehicles_per_hour": 1e6}}, ("traffic", "vehicles_per_hour")),
    ({"traffic": {"cyclists_per_hour": 1801}}, ("traffic", "cyclists_per_hour")),
    ({"traffic": {"pedestrians_per_hour": 1e5}}, ("traffic", "pedestrians_per_hour")),
    ({"ego": {"start_speed_mps": 41.0}}, ("ego", "start_speed_mps")),
    ({"ego": {"start_distance_m": 1e9}}, ("ego", "start_distance_m")),
    ({"lights": {"elapsed_s": 1e9}}, ("lights", "elapsed_s")),
])
def test_scenario_numbers_are_bounded(client: TestClient, tiny_scenario: dict[str, Any], field_named: Any,
                                      patch: dict[str, Any], loc: tuple[str, ...]) -> None:
    before = client.get("/api/scenarios").headers[TOTAL_HEADER]
    response = client.post("/api/scenarios", json={**tiny_scenario, **patch})
    assert field_named(response, *loc), response.json()
    batch = client.post("/api/batches", json={"scenario": {**tiny_scenario, **patch}})
    assert field_named(batch, "scenario", *loc), batch.json()
    assert client.get("/api/scenarios").headers[TOTAL_HEADER] == before


def test_the_schema_shows_the_bounds(client: TestClient) -> None:
    schema = client.get("/api/scenarios/schema").json()
    props, defs = schema["properties"], schema["$defs"]
    assert props["runs"]["maximum"] == 10_000 and props["timeout_s"]["maximum"] == 3600
    assert props["warmup_s"]["maximum"] == 600
    assert defs["TrafficSpec"]["properties"]["vehicles_per_hour"]["maximum"] == 1800
    assert defs["EgoSpec"]["properties"]["start_speed_mps"]["maximum"] == 40
    assert defs["OverspeedSpec"]["properties"]["excess"]["maximum"] == 1


@pytest.mark.parametrize(("body", "loc"), [
    ({"runs": 10**12}, ("runs",)),
    ({"runs": 10**30}, ("runs",)),
    ({"workers": 65}, ("workers",)),
    ({"workers": 256}, ("workers",)),
    ({"scenario_id": 2**31}, ("scenario_id",)),
    ({"scenario_id": 2**63}, ("scenario_id",)),
])
def test_batch_numbers_are_bounded(client: TestClient, tiny_scenario: dict[str, Any], field_named: Any,
                                   body: dict[str, Any], loc: tuple[str, ...]) -> None:
    before = client.get("/api/batches").headers[TOTAL_HEADER]
    response = client.post("/api/batches", json={"scenario": tiny_scenario, **body}
                           if "scenario_id" not in body else body)
    assert field_named(response, *loc), response.json()
    assert client.get("/api/batches").headers[TOTAL_HEADER] == before


def test_workers_beyond_the_servers_setting(client: TestClient, tiny_scenario: dict[str, Any],
                                            field_named: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    settings = client.app.state.settings
    # (State's attributes live in its _state dict: monkeypatch.setattr would delete it on undo)
    monkeypatch.setitem(client.app.state._state, "settings", settings.model_copy(update={"max_batch_workers": 2}))
    response = client.post("/api/batches", json={"scenario": tiny_scenario, "workers": 3})
    assert field_named(response, "workers") and "at most 2" in response.text


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e400"])
def test_nan_and_infinity_are_422(client: TestClient, tiny_scenario: dict[str, Any], literal: str) -> None:
    """Python's JSON parser reads these literals; each is a 422 naming the field, not a 500."""
    stored = client.post("/api/scenarios", json=tiny_scenario).json()["id"]
    bodies = {
        "/api/batches": [f'{{"scenario_id": {stored}, "runs": {literal}}}',
                         f'{{"scenario_id": {stored}, "workers": {literal}}}',
                         f'{{"scenario": {{"version": 1, "name": "n", "intersection": "a_single_lane", '
                         f'"task": "left", "warmup_s": {literal}}}}}'],
        "/api/live": [f'{{"scenario_id": {stored}, "speed": {literal}}}',
                      f'{{"scenario_id": {stored}, "seed": {literal}}}'],
        "/api/scenarios": [f'{{"version": 1, "name": "n", "intersection": "a_single_lane", "task": "left", '
                           f'"timeout_s": {literal}}}'],
        "/api/scenarios/validate": [f'{{"version": 1, "name": "n", "intersection": "a_single_lane", '
                                    f'"task": "left", "rho": {literal}}}'],
    }
    for path, texts in bodies.items():
        for text in texts:
            response = client.post(path, content=text, headers={"content-type": "application/json"})
            if path == "/api/scenarios/validate":
                assert response.status_code == 200 and not response.json()["valid"], response.text
                continue
            assert response.status_code == 422, (path, text, response.text)
            assert response.json()["detail"], response.text


@pytest.mark.parametrize("big", BIG_IDS)
def test_ids_beyond_their_columns_are_422(client: TestClient, big: int) -> None:
    for method, path in [("GET", f"/api/batches/{big}"), ("GET", f"/api/batches/{big}/episodes"),
                         ("GET", f"/api/batches/{big}/events"), ("POST", f"/api/batches/{big}/cancel"),
                         ("GET", f"/api/scenarios/{big}"), ("DELETE", f"/api/scenarios/{big}"),
                         ("GET", f"/api/episodes/{big}/0"), ("GET", f"/api/episodes/1/{big}"),
                         ("GET", f"/api/episodes/1/{big}/trace"), ("GET", f"/api/playback/{big}/0"),
                         ("POST", f"/api/playback/1/{big}"), ("GET", f"/api/live/{big}"),
                         ("POST", f"/api/live/{big}/stop"), ("GET", f"/api/batches?scenario_id={big}"),
                         ("GET", f"/api/reports?batch={big}"), ("GET", f"/api/batches?offset={big * 2**33}")]:
        response = client.request(method, path)
        assert response.status_code == 422, (method, path, response.text)
    live = client.post("/api/live", json={"scenario_id": big})
    assert live.status_code == 422, live.text


def test_unknown_ids_in_range_are_404(client: TestClient) -> None:
    top = 2**31 - 1
    for path in (f"/api/batches/{top}", f"/api/scenarios/{top}", f"/api/episodes/{top}/{top}",
                 f"/api/reports?batch={top}"):
        assert client.get(path).status_code == 404, path
    assert client.post(f"/api/batches/{top}/cancel").status_code == 404


def test_bodies_have_a_size_limit(client: TestClient, tiny_scenario: dict[str, Any]) -> None:
    """The JSON limit (settings: json_body_max_bytes): refused unread when declared, and as soon as
    it is passed when the body comes in chunks; nothing stored."""
    limit = client.app.state.settings.json_body_max_bytes
    before = client.get("/api/scenarios").headers[TOTAL_HEADER]
    big = {**tiny_scenario, "name": "big", "description": "x" * limit}
    declared = client.post("/api/scenarios", json=big)
    assert declared.status_code == 413 and "limit" in declared.json()["detail"]

    def chunks() -> Any:
        text = '{"version": 1, "name": "c", "intersection": "a_single_lane", "task": "left", "description": "'
        yield text.encode()
        for _ in range(limit // 65536 + 2):
            yield b"y" * 65536
        yield b'"}'

    chunked = client.post("/api/scenarios", content=chunks(), headers={"content-type": "application/json"})
    assert chunked.status_code == 413
    assert client.get("/api/scenarios").headers[TOTAL_HEADER] == before
    long = client.post("/api/scenarios", json={**tiny_scenario, "name": "long", "description": "z" * 10_001})
    assert long.status_code == 422 and long.json()["detail"][0]["loc"][-1] == "description"
    ok = client.post("/api/scenarios", json={**tiny_scenario, "name": "fits", "description": "z" * 10_000})
    assert ok.status_code == 201


@pytest.mark.parametrize("path", ["/api/scenarios", "/api/batches", "/api/intersections", "/api/intersections/uploads",
                                  "/api/policies", "/api/live"])
def test_every_list_is_paged(client: TestClient, tiny_scenario: dict[str, Any], path: str) -> None:
    for i in range(3):
        client.post("/api/scenarios", json={**tiny_scenario, "name": f"paged-{i}"})
    full = client.get(path)
    total = int(full.headers[TOTAL_HEADER])
    assert len(full.json()) == min(total, 100)
    if total >= 2:
        assert client.get(path, params={"limit": 1, "offset": 1}).json() == full.json()[1:2]
    assert client.get(path, params={"limit": 100_000}).status_code == 422
    assert client.get(path, params={"limit": 0}).status_code == 422
    assert client.get(path, params={"offset": -1}).status_code == 422
    assert client.get(path, params={"offset": total}).json() == []


def test_episodes_are_paged(client: TestClient, finished_batch: dict[str, Any]) -> None:
    url = f"/api/batches/{finished_batch['id']}/episodes"
    every = client.get(url)
    assert every.headers[TOTAL_HEADER] == "2" and [e["run_index"] for e in every.json()] == [0, 1]
    assert [e["run_index"] for e in client.get(url, params={"limit": 1, "offset": 1}).json()] == [1]
    assert client.get(url, params={"outcome": "exploded"}).status_code == 422


@pytest.mark.parametrize("name", ["docker-compose.yml", "../docker-compose.yml", "scenarios/intersections/a_single_lane.yaml",
                                  "x.net.xml", "Makefile", "%2e%2e%2fREADME.md"])
def test_intersection_names_never_reach_files(client: TestClient, name: str) -> None:
    for suffix in ("", "/internal-lanes", "/paths?task=left"):
        response = client.get(f"/api/intersections/{name}{suffix}")
        assert response.status_code == 404, (name, suffix, response.text)
