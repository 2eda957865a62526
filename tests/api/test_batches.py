"""Batches: invalid requests are 422s naming the field (and store nothing); a tiny batch runs in
the background while the API answers, streams its progress as Server-Sent Events and ends with
a summary; a long batch can be cancelled; reports over finished batches."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from support import SUMO_CROSS_NET, sumo_example

FAST_S = 1.0  # [s] an answer while a batch runs must come faster than this


def _batch_count(client: TestClient) -> int:
    return int(client.get("/api/batches").headers["x-total-count"])


def _scenario_count(client: TestClient) -> int:
    return int(client.get("/api/scenarios").headers["x-total-count"])


@pytest.mark.parametrize(("body", "loc"), [
    ({"scenario_id": 1, "runs": "2"}, ("runs",)),                  # wrong type
    ({"scenario_id": 1, "runs": -1}, ("runs",)),                   # negative runs
    ({"scenario_id": 1, "runs": 0}, ("runs",)),
    ({"scenario_id": 1, "workers": 0}, ("workers",)),
    ({"scenario_id": 1, "traces": "some"}, ("traces",)),
    ({"scenario_id": 1, "colour": "red"}, ("colour",)),            # unknown field
    ({"scenario_id": 1, "policy": "nonsense"}, ("policy",)),       # bad policy
    ({"scenario_id": 1, "policy": "/etc/passwd"}, ("policy",)),    # never a server path
    ({"scenario_id": 1, "policy": 3}, ("policy",)),
    ({"policy": "rule"}, ("scenario_id",)),                        # no scenario at all
    ({"scenario_id": 987654}, ("scenario_id",)),                   # a missing scenario id
    ({"scenario_id": "one"}, ("scenario_id",)),
    ({"scenario_id": 1, "scenario": {"version": 1}}, ("scenario_id",)),  # both
    ({"scenario": {"version": 1, "name": "x", "intersection": "a_single_lane", "task": "up"}},
     ("scenario", "task")),                                        # invalid inline scenario
    ({"scenario": {"version": 1, "name": "x", "intersection": "a_single_lane", "task": "left",
                   "runs": -2}}, ("scenario", "runs")),
])
def test_invalid_batch_names_the_field_and_stores_nothing(
        client: TestClient, tiny_scenario: dict[str, Any], field_named: Any,
        body: dict[str, Any], loc: tuple[str, ...]) -> None:
    stored = client.post("/api/scenarios", json=tiny_scenario).json()["id"]
    if body.get("scenario_id") == 1:
        body = {**body, "scenario_id": stored}
    scenarios_before, batches_before = _scenario_count(client), _batch_count(client)
    response = client.post("/api/batches", json=body)
    assert field_named(response, *loc), response.json()
    assert _batch_count(client) == batches_before
    assert _scenario_count(client) == scenarios_before


def test_non_json_and_unknown_ids(client: TestClient) -> None:
    assert client.post("/api/batches", content=b"runs=2",
                       headers={"content-type": "application/x-www-form-urlencoded"}).status_code == 422
    assert client.get("/api/batches/999999").status_code == 404
    assert client.get("/api/batches/999999/episodes").status_code == 404
    assert client.get("/api/batches/999999/events").status_code == 404
    assert client.post("/api/batches/999999/cancel").status_code == 404
    assert client.get("/api/batches", params={"status": "sleeping"}).status_code == 422


def _events(client: TestClient, batch_id: int) -> list[tuple[str, dict[str, Any]]]:
    """Read the whole event stream of a batch (it closes when the batch has ended)."""
    events, name = [], None
    with client.stream("GET", f"/api/batches/{batch_id}/events") as response:
        assert response.status_code == 200
        assert response.headers["content-type"].startswith("text/event-stream")
        for line in response.iter_lines():
            if line.startswith("event: "):
                name = line.removeprefix("event: ")
            elif line.startswith("data: "):
                events.append((name, json.loads(line.removeprefix("data: "))))
    return events


def test_tiny_batch_end_to_end(client: TestClient, tiny_batch: int) -> None:
    events = _events(client, tiny_batch)
    kinds = [k for k, _ in events]
    assert kinds[-1] == "end" and kinds.count("end") == 1 and "progress" in kinds
    progress = [d for k, d in events if k == "progress"]
    assert [p["done"] for p in progress] == sorted(p["done"] for p in progress)
    assert progress[-1]["done"] == progress[-1]["total"] == 2
    end = events[-1][1]
    assert end["status"] == "done" and end["summary"]["recorded"] == 2
    assert all(data["warnings"] == [] for _, data in events)

    body = client.get(f"/api/batches/{tiny_batch}").json()
    assert body["status"] == "done" and body["policy"] == "rule" and body["scenario"] == "api-tiny-left"
    assert body["warnings"] == []  # the catalogue's internal lanes follow the candidate paths
    timing = {k: body["progress"].pop(k) for k in ("elapsed_s", "since_start", "rate_per_min", "eta_s")}
    assert body["progress"] == {"done": 2, "total": 2, "passed": body["summary"]["passed"],
                                "errors": 0, "fraction": 1.0}
    assert timing["since_start"] == 2 and timing["elapsed_s"] >= 0 and timing["eta_s"] is None  # ended
    assert timing["rate_per_min"] is None or timing["rate_per_min"] > 0  # None: both within a second
    summary = body["summary"]
    assert sum(summary["outcome_counts"].values()) == 2 and summary["errors"] == 0
    assert 0.0 <= summary["wilson_low"] <= summary["wilson_high"] <= 1.0
    if summary["passed"]:
        assert summary["pass_rate"] == summary["passed"] / 2 and summary["travel_time_mean_s"] > 0
    assert body["workers"] == 1 and body["executor"] == "local" and body["finished_at"]

    episodes = client.get(f"/api/batches/{tiny_batch}/episodes").json()
    assert [e["run_index"] for e in episodes] == [0, 1]
    assert all(e["has_trace"] for e in episodes), "traces: all"
    assert tiny_batch in [b["id"] for b in client.get("/api/batches").json()]
    # an ended batch's stream answers at once with its state and the end
    assert [k for k, _ in _events(client, tiny_batch)] == ["progress", "end"]
    assert client.post(f"/api/batches/{tiny_batch}/cancel").status_code == 409


def test_cancel_a_running_batch_while_the_api_answers(client: TestClient, tiny_scenario: dict[str, Any],
                                                      wait_for: Any) -> None:
    tiny_scenario["name"] = "api-long-left"
    started = time.monotonic()
    response = client.post("/api/batches", json={"scenario": tiny_scenario, "runs": 40, "workers": 1,
                                                 "traces": "none"})
    assert response.status_code == 202 and time.monotonic() - started < FAST_S
    batch_id = response.json()["id"]
    assert response.json()["status"] == "queued"
    wait_for(batch_id, ("running",), timeout_s=60)
    for url in ("/api/health", f"/api/batches/{batch_id}", "/api/scenarios", "/api/policies"):
        t0 = time.monotonic()
        assert client.get(url).status_code == 200
        assert time.monotonic() - t0 < FAST_S, f"{url} waited on the batch"
    assert client.get(f"/api/batches/{batch_id}").json()["status"] == "running"

    cancel = client.post(f"/api/batches/{batch_id}/cancel")
    assert cancel.status_code == 202 and cancel.json()["status"] == "cancelling"
    body = wait_for(batch_id, ("cancelled", "done", "failed"), timeout_s=30)
    assert body["status"] == "cancelled" and body["progress"]["done"] < 40
    assert _events(client, batch_id)[-1][1]["status"] == "cancelled"
    assert client.post(f"/api/batches/{batch_id}/cancel").status_code == 409


def test_cancel_a_queued_batch_nobody_runs(client: TestClient, tiny_scenario: dict[str, Any]) -> None:
    from crossroads.store import crud

    sid = client.post("/api/scenarios", json={**tiny_scenario, "name": "orphan"}).json()["id"]
    with client.app.state.store.session() as session:  # e.g. left behind by a stopped server
        batch = crud.create_batch(session=session, scenario=crud.get_scenario(session=session, scenario_id=sid),
                                  policy=crud.get_or_create_policy(session=session, ref="rule"), runs=3)
    response = client.post(f"/api/batches/{batch.id}/cancel")
    assert response.status_code == 202 and response.json()["status"] == "cancelled"
    assert client.get(f"/api/batches/{batch.id}").json()["status"] == "cancelled"


def test_a_batch_that_cannot_start_fails_with_its_reason(client: TestClient, tiny_scenario: dict[str, Any],
                                                          wait_for: Any) -> None:
    # the fake checkpoint is listed (so accepted) but is no checkpoint: the batch fails, visibly
    response = client.post("/api/batches", json={"scenario": tiny_scenario, "policy": "fake", "runs": 1})
    assert response.status_code == 202
    body = wait_for(response.json()["id"], ("failed", "done", "cancelled"), timeout_s=60)
    assert body["status"] == "failed" and body["error"]


def test_a_batch_on_a_net_whose_internal_lanes_run_off_the_paths_keeps_the_warning(
        client: TestClient, tiny_scenario: dict[str, Any], data_dir: Path, wait_for: Any) -> None:
    """netconvert drew cross.net.xml's left turns up to 3 m from the paper's fixed-ρ candidate paths:
    a batch on it stores the warning POST /scenarios/validate gives, and every answer about it
    carries it."""
    upload = client.post("/api/intersections/upload", files={
        "file": ("cross.net.xml", sumo_example(SUMO_CROSS_NET).read_bytes(), "application/xml")}).json()
    scenario = {**tiny_scenario, "name": "api-cross-left", "intersection": {"net": upload["net"]}, "rho": 0.6}
    (expected,) = client.post("/api/scenarios/validate", json=scenario).json()["warnings"]
    response = client.post("/api/batches", json={"scenario": scenario, "runs": 1, "workers": 1,
                                                 "traces": "none"})
    assert response.status_code == 202, response.text
    batch_id = response.json()["id"]
    assert response.json()["warnings"] == [expected["message"]]  # said at once, before any run
    body = wait_for(batch_id, ("done", "failed", "cancelled"))
    assert body["status"] == "done" and body["warnings"] == [expected["message"]]
    events = _events(client, batch_id)  # a client that only follows the stream sees it too
    assert events and all(data["warnings"] == body["warnings"] for _, data in events)
    # named as uploaded, with the digest's start; the server's data directory stays out of it
    assert f"cross.net.xml (upload {upload['id'][:12]}) (left from" in expected["message"] and str(data_dir) not in expected["message"]
    listed = {b["id"]: b for b in client.get("/api/batches", params={"limit": 1000}).json()}
    assert listed[batch_id]["warnings"] == body["warnings"]
    html = client.get("/api/reports", params={"batch": [batch_id], "format": "html"}).text
    assert "<h2>Warnings</h2>" in html and "api-cross-left" in html


def test_reports(client: TestClient, finished_batch: dict[str, Any]) -> None:
    batch_id = finished_batch["id"]
    html = client.get("/api/reports", params={"batch": [batch_id], "format": "html"})
    assert html.status_code == 200 and html.headers["content-type"].startswith("text/html")
    assert "<html" in html.text and "api-tiny-left" in html.text
    csv = client.get("/api/reports", params={"batch": [batch_id, batch_id], "format": "csv"})
    assert csv.status_code == 200 and csv.headers["content-type"].startswith("text/csv")
    lines = csv.text.strip().splitlines()
    assert lines[0].startswith("batch_id,") and len(lines) == 2

    assert client.get("/api/reports").status_code == 422
    assert client.get("/api/reports", params={"batch": [batch_id], "format": "pdf"}).status_code == 422
    assert client.get("/api/reports", params={"batch": ["x"]}).status_code == 422
    assert client.get("/api/reports", params={"batch": [999999]}).status_code == 404
