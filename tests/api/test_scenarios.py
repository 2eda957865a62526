"""Scenarios: create, read, update, delete, validate, the JSON Schema, YAML files out and in; invalid input is a 422
naming the field, and nothing of it is stored."""

from __future__ import annotations

from typing import Any

import pytest
import yaml
from fastapi.testclient import TestClient

from crossroads.store import crud


def _count(client: TestClient) -> int:
    return int(client.get("/api/scenarios").headers["x-total-count"])


def test_create_read_update_delete(client: TestClient, tiny_scenario: dict[str, Any]) -> None:
    tiny_scenario["name"] = "crud-me"
    created = client.post("/api/scenarios", json=tiny_scenario)
    assert created.status_code == 201, created.text
    body = created.json()
    assert body["name"] == "crud-me" and len(body["content_hash"]) == 64 and body["batches"] == 0
    assert body["spec"]["lights"]["elapsed_s"] == 0.0 and body["spec"]["rho"] is None, "defaults are filled in"
    sid = body["id"]

    again = client.post("/api/scenarios", json=dict(reversed(list(tiny_scenario.items()))))
    assert again.status_code == 200 and again.json()["id"] == sid, "same content: same row"
    assert client.get(f"/api/scenarios/{sid}").json()["content_hash"] == body["content_hash"]
    assert sid in [s["id"] for s in client.get("/api/scenarios", params={"limit": 1000}).json()]

    changed = {**tiny_scenario, "task": "right"}
    updated = client.put(f"/api/scenarios/{sid}", json=changed)
    assert updated.status_code == 200, updated.text
    assert updated.json()["spec"]["task"] == "right"
    assert updated.json()["content_hash"] != body["content_hash"]

    assert client.delete(f"/api/scenarios/{sid}").status_code == 204
    assert client.get(f"/api/scenarios/{sid}").status_code == 404
    assert client.delete(f"/api/scenarios/{sid}").status_code == 404


@pytest.mark.parametrize(("change", "loc"), [
    ({"runs": "5"}, ("runs",)),                                    # wrong type (no coercion)
    ({"runs": -3}, ("runs",)),                                     # negative runs
    ({"runs": 2.5}, ("runs",)),
    ({"colour": "red"}, ("colour",)),                              # unknown field
    ({"traffic": {"vehicles_per_hour": 100, "trucks": 3}}, ("traffic", "trucks")),
    ({"task": "sideways"}, ("task",)),
    ({"version": 2}, ("version",)),
    ({"name": "has spaces"}, ("name",)),
    ({"intersection": "atlantis"}, ("intersection",)),             # unknown catalogue name
    ({"intersection": 5}, ("intersection",)),
    ({"intersection": {"net": "/etc/hosts.net.xml"}}, ("intersection", "net")),  # not an upload
    ({"intersection": {"net": "uploads/../../x.net.xml"}}, ("intersection", "net")),
    ({"intersection": {"net": "uploads/nothing.net.xml"}}, ("intersection", "net")),
    ({"abnormal": {"overspeed": {"share": 1.5, "excess": 0.1}}}, ("abnormal", "overspeed", "share")),
    ({"warmup_s": float("nan")}, None),                           # not even JSON: rejected somewhere
    ({"seed": -1}, ("seed",)),
    ({"perception_noise": "yes"}, ("perception_noise",)),
])
def test_invalid_scenario_names_the_field_and_stores_nothing(
        client: TestClient, tiny_scenario: dict[str, Any], field_named: Any,
        change: dict[str, Any], loc: tuple[str, ...] | None) -> None:
    before = _count(client)
    data = {**tiny_scenario, **change}
    if loc is None:
        response = client.post("/api/scenarios", content=b'{"version": 1, "warmup_s": NaN}',
                               headers={"content-type": "application/json"})
        assert response.status_code == 422
    else:
        response = client.post("/api/scenarios", json=data)
        assert field_named(response, *loc), response.json()
        check = client.post("/api/scenarios/validate", json=data).json()
        assert check["valid"] is False and ".".join(loc) in [p["field"] for p in check["problems"]]
    assert _count(client) == before


@pytest.mark.parametrize("field", ["version", "name", "intersection", "task"])
def test_missing_required_field(client: TestClient, tiny_scenario: dict[str, Any], field_named: Any,
                                field: str) -> None:
    del tiny_scenario[field]
    assert field_named(client.post("/api/scenarios", json=tiny_scenario), field)


@pytest.mark.parametrize("body", [[1, 2], "a string", None])
def test_body_that_is_not_a_mapping(client: TestClient, body: Any) -> None:
    response = client.post("/api/scenarios", json=body)
    assert response.status_code == 422
    assert response.json()["detail"][0]["loc"][0] == "body"


def test_not_json_at_all(client: TestClient) -> None:
    response = client.post("/api/scenarios", content=b"version: 1\n",
                           headers={"content-type": "application/json"})
    assert response.status_code == 422


def test_validate_reports_every_problem(client: TestClient, tiny_scenario: dict[str, Any]) -> None:
    assert client.post("/api/scenarios/validate", json=tiny_scenario).json() == {"valid": True, "problems": [], "warnings": []}
    bad = {**tiny_scenario, "runs": 0, "rho": 2.0, "extra": 1}
    body = client.post("/api/scenarios/validate", json=bad).json()
    assert body["valid"] is False
    assert {p["field"] for p in body["problems"]} == {"runs", "rho", "extra"}
    assert all(p["message"] for p in body["problems"])


def test_schema(client: TestClient) -> None:
    schema = client.get("/api/scenarios/schema").json()
    assert schema["title"] == "Crossroads scenario"
    assert {"version", "name", "intersection", "task"} <= set(schema["required"])
    assert "abnormal" in schema["properties"]


def test_update_invalid_changes_nothing(client: TestClient, tiny_scenario: dict[str, Any],
                                        field_named: Any) -> None:
    tiny_scenario["name"] = "keep-me"
    sid = client.post("/api/scenarios", json=tiny_scenario).json()["id"]
    before = client.get(f"/api/scenarios/{sid}").json()
    assert field_named(client.put(f"/api/scenarios/{sid}", json={**tiny_scenario, "task": 3}), "task")
    assert client.get(f"/api/scenarios/{sid}").json() == before
    assert client.put("/api/scenarios/999999", json=tiny_scenario).status_code == 404
    assert client.get("/api/scenarios/not-a-number").status_code == 422


def test_update_to_an_existing_scenario_conflicts(client: TestClient, tiny_scenario: dict[str, Any]) -> None:
    a = client.post("/api/scenarios", json={**tiny_scenario, "name": "twin-a"}).json()["id"]
    client.post("/api/scenarios", json={**tiny_scenario, "name": "twin-b"})
    response = client.put(f"/api/scenarios/{a}", json={**tiny_scenario, "name": "twin-b"})
    assert response.status_code == 409


def test_scenario_with_batches_is_read_only(client: TestClient, tiny_scenario: dict[str, Any]) -> None:
    tiny_scenario["name"] = "has-results"
    sid = client.post("/api/scenarios", json=tiny_scenario).json()["id"]
    store = client.app.state.store
    with store.session() as session:  # a queued batch, never run: enough to make it read-only
        scenario = crud.get_scenario(session=session, scenario_id=sid)
        policy = crud.get_or_create_policy(session=session, ref="rule")
        crud.create_batch(session=session, scenario=scenario, policy=policy, runs=1)
    assert client.get(f"/api/scenarios/{sid}").json()["batches"] == 1
    assert client.put(f"/api/scenarios/{sid}", json={**tiny_scenario, "runs": 3}).status_code == 409
    assert client.delete(f"/api/scenarios/{sid}").status_code == 409
    assert client.get(f"/api/scenarios/{sid}").status_code == 200


def test_policies_lists_rule_and_checkpoints_with_cards(client: TestClient) -> None:
    policies = {p["name"]: p for p in client.get("/api/policies").json()}
    assert policies["rule"]["kind"] == "builtin"
    assert policies["fake"]["kind"] == "checkpoint" and policies["fake"]["file"] == "fake.pt"
    assert policies["fake"]["card"] == {"algorithm": "APG", "iterations": 1} and not policies["fake"]["shield"]
    shielded = policies["fake+shield"]
    assert shielded["shield"] and shielded["file"] == "fake.pt" and shielded["card"] == policies["fake"]["card"]
    assert list(policies).index("fake+shield") == list(policies).index("fake") + 1


@pytest.mark.parametrize(("change", "loc", "words"), [
    ({"approach": "nowhere_in"}, ("approach",), "south_in"),          # lists the approaches
    ({"ego": {"entrance_lane": "south_in_9"}}, ("ego", "entrance_lane"), "south_in_4"),
    ({"ego": {"entrance_lane": "south_in_2"}}, ("ego", "entrance_lane"), "does not lead left"),
    ({"ego": {"entrance_lane": "north_in_4"}}, ("ego", "entrance_lane"), "not an entrance lane"),
    ({"ego": {"start_distance_m": 400.0}}, ("ego", "start_distance_m"), "at most"),
    ({"ego": {"start_distance_m": 0.0}}, ("ego", "start_distance_m"), "greater than 0"),
    ({"ego": {"start_speed_mps": -1.0}}, ("ego", "start_speed_mps"), "greater than or equal"),
    ({"lights": {"phase": 8}}, ("lights", "phase"), "0 to 7"),
    ({"lights": {"phase": 2, "elapsed_s": 3.0}}, ("lights", "elapsed_s"), "lasts 3 s"),
    ({"lights": {"phase": 0, "elapsed_s": -1.0}}, ("lights", "elapsed_s"), "greater than or equal"),
])
def test_what_the_network_contradicts_names_the_field(
        client: TestClient, tiny_scenario: dict[str, Any], field_named: Any,
        change: dict[str, Any], loc: tuple[str, ...], words: str) -> None:
    data = {**tiny_scenario, "intersection": "c_three_lane", **change}
    before = _count(client)
    response = client.post("/api/scenarios", json=data)
    assert field_named(response, *loc), response.json()
    assert words in response.json()["detail"][0]["msg"]
    check = client.post("/api/scenarios/validate", json=data).json()
    assert check["valid"] is False and [p["field"] for p in check["problems"]] == [".".join(loc)]
    assert _count(client) == before


def test_ego_start_and_lights_that_fit_the_network(client: TestClient, tiny_scenario: dict[str, Any]) -> None:
    data = {**tiny_scenario, "name": "ego-start", "intersection": "c_three_lane", "approach": "south_in",
            "ego": {"entrance_lane": "south_in_4", "start_distance_m": 25.0, "start_speed_mps": 5.0},
            "lights": {"phase": 4, "elapsed_s": 20.0}}
    created = client.post("/api/scenarios", json=data)
    assert created.status_code == 201, created.text
    spec = created.json()["spec"]
    assert spec["ego"] == {"entrance_lane": "south_in_4", "start_distance_m": 25.0, "start_speed_mps": 5.0}
    assert spec["lights"] == {"ego": None, "phase": 4, "elapsed_s": 20.0, "program": None}
    assert spec["approach"] == "south_in"
    geometry = client.get("/api/intersections/c_three_lane").json()
    # walk, pedestrian clearance, yellow, all-red of each axis (intersections/build.py)
    assert [p["duration_s"] for p in geometry["program"]["phases"]] == [50.0, 10.0, 3.0, 2.0,
                                                                      23.0, 10.0, 3.0, 2.0]
    links = [m["link"] for m in geometry["signal_links"]["south_in"] if m["lane"] == "south_in_4" and m["turn"] == "left"]
    assert links and all(geometry["program"]["phases"][0]["state"][k] in "Gg" for k in links), \
        "phase 0: the ego's axis green"


def test_a_scenario_as_a_yaml_file_and_back(client: TestClient, tiny_scenario: dict[str, Any]) -> None:
    stored = client.post("/api/scenarios", json={**tiny_scenario, "name": "yaml-round-trip"}).json()
    download = client.get(f"/api/scenarios/{stored['id']}/scenario.yaml")
    assert download.status_code == 200 and download.headers["content-type"].startswith("application/yaml")
    assert 'filename="yaml-round-trip.yaml"' in download.headers["content-disposition"]
    assert download.text.startswith(f"# Crossroads scenario #{stored['id']} (yaml-round-trip)")
    assert yaml.safe_load(download.text) == stored["spec"]
    yaml_type = {"content-type": "application/yaml"}
    again = client.post("/api/scenarios/import", content=download.text, headers=yaml_type)
    assert again.status_code == 200 and again.json()["id"] == stored["id"], "the same content: the same row"
    renamed = download.text.replace("name: yaml-round-trip", "name: yaml-imported")
    imported = client.post("/api/scenarios/import", content=renamed, headers=yaml_type)
    assert imported.status_code == 201 and imported.json()["name"] == "yaml-imported"
    assert client.get("/api/scenarios/999999/scenario.yaml").status_code == 404


@pytest.mark.parametrize(("text", "loc", "says"), [
    ("name: [unclosed\n", ["body"], "line 2"),
    ("- a list\n", ["body"], "mapping"),
    ("", ["body"], "required"),  # no file at all
    ("# only a comment\n", ["body"], "empty file"),
])
def test_an_import_that_is_not_a_scenario_file(client: TestClient, text: str, loc: list[str], says: str) -> None:
    response = client.post("/api/scenarios/import", content=text, headers={"content-type": "application/yaml"})
    assert response.status_code == 422, response.text
    detail = response.json()["detail"]
    assert any(d["loc"] == loc and says in d["msg"] for d in detail), detail


def test_an_imported_scenario_is_checked_like_a_posted_one(client: TestClient, tiny_scenario: dict[str, Any],
                                                           field_named: Any) -> None:
    bad = yaml.safe_dump({**tiny_scenario, "name": "yaml-bad", "runs": 0})
    response = client.post("/api/scenarios/import", content=bad, headers={"content-type": "application/yaml"})
    assert field_named(response, "runs")
    assert not any(s["name"] == "yaml-bad" for s in client.get("/api/scenarios", params={"limit": 1000}).json())
