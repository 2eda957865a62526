"""Episodes: one run's result and its trace (every stride-th frame); 404 where there is none."""

from __future__ import annotations

from typing import Any

from fastapi.testclient import TestClient

from crossroads.store import crud


def test_episode_result(client: TestClient, finished_batch: dict[str, Any]) -> None:
    batch_id = finished_batch["id"]
    body = client.get(f"/api/episodes/{batch_id}/1").json()
    assert body["batch_id"] == batch_id and body["run_index"] == 1
    assert body["outcome"] in ("passed", "collision", "red_light", "off_road", "timeout")
    assert body["passed"] == (body["outcome"] == "passed") and body["has_trace"]
    assert body["steps"] > 0 and body["wall_s"] > 0


def test_trace_with_stride(client: TestClient, finished_batch: dict[str, Any]) -> None:
    batch_id = finished_batch["id"]
    full = client.get(f"/api/episodes/{batch_id}/0/trace").json()
    assert full["header"]["scenario"] == "api-tiny-left"
    frames = full["frames"]
    assert len(frames) > 5 and {"ego", "participants", "speed_mode"} <= set(frames[0])
    thin = client.get(f"/api/episodes/{batch_id}/0/trace", params={"stride": 5}).json()["frames"]
    assert len(thin) == len(range(0, len(frames), 5)) + (1 if (len(frames) - 1) % 5 else 0)
    assert thin[0] == frames[0] and thin[-1] == frames[-1], "the last frame is always kept"


def test_bad_requests(client: TestClient, finished_batch: dict[str, Any], field_named: Any) -> None:
    batch_id = finished_batch["id"]
    assert field_named(client.get(f"/api/episodes/{batch_id}/0/trace", params={"stride": 0}), "stride")
    assert field_named(client.get(f"/api/episodes/{batch_id}/0/trace", params={"stride": "x"}), "stride")
    assert client.get(f"/api/episodes/{batch_id}/7").status_code == 404
    assert client.get(f"/api/episodes/{batch_id}/7/trace").status_code == 404
    assert client.get("/api/episodes/999999/0").status_code == 404
    assert client.get(f"/api/episodes/{batch_id}/first").status_code == 422


def test_no_trace_kept_is_404(client: TestClient, tiny_scenario: dict[str, Any]) -> None:
    sid = client.post("/api/scenarios", json={**tiny_scenario, "name": "no-traces"}).json()["id"]
    with client.app.state.store.session() as session:
        batch = crud.create_batch(session=session, scenario=crud.get_scenario(session=session, scenario_id=sid),
                                  policy=crud.get_or_create_policy(session=session, ref="rule"), runs=1,
                                  traces="none")
        crud.record_episode(session=session, batch_id=batch.id, run_index=0, seed=1,
                            result={"outcome": "passed", "travel_time_s": 4.2, "steps": 80, "time_s": 8.0})
    assert client.get(f"/api/episodes/{batch.id}/0").json()["has_trace"] is False
    response = client.get(f"/api/episodes/{batch.id}/0/trace")
    assert response.status_code == 404 and "no trace" in response.json()["detail"]


def test_the_closest_footprint_gap_is_kept(client: TestClient, tiny_scenario: dict[str, Any],
                                           finished_batch: dict[str, Any]) -> None:
    sid = client.post("/api/scenarios", json={**tiny_scenario, "name": "gap-kept"}).json()["id"]
    with client.app.state.store.session() as session:
        batch = crud.create_batch(session=session, scenario=crud.get_scenario(session=session, scenario_id=sid),
                                  policy=crud.get_or_create_policy(session=session, ref="rule"), runs=2,
                                  traces="none")
        crud.record_episode(session=session, batch_id=batch.id, run_index=0, seed=1,
                            result={"outcome": "collision", "steps": 30, "time_s": 3.0, "min_distance_m": 3.9,
                                    "min_gap_m": 0.0, "detail": "hit vehicle veh1"})
        crud.record_episode(session=session, batch_id=batch.id, run_index=1, seed=2,
                            result={"outcome": "passed", "travel_time_s": 4.0, "steps": 80, "time_s": 8.0,
                                    "min_distance_m": None, "min_gap_m": float("inf")})
    hit, alone = client.get(f"/api/batches/{batch.id}/episodes").json()
    assert (hit["min_gap_m"], hit["min_distance_m"]) == (0.0, 3.9), "touching: no gap, centres 3.9 m apart"
    assert alone["min_gap_m"] is None, "nobody closed in"
    # a real batch records the gap its episodes measured
    recorded = client.get(f"/api/batches/{finished_batch['id']}/episodes").json()
    assert all("min_gap_m" in e for e in recorded)
