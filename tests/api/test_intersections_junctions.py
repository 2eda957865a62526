"""Networks with several signalised junctions: the geometry lists them, every route reads the one
named by ``?junction=`` (a 422 naming ``junction`` for one it cannot), and per approach the tasks
that have a candidate path, which agree with what the paths route answers.

The networks ship with SUMO itself (written by others): a corridor of three 4-way junctions, a
grid of six without left turns, and a 4-way whose legs carry pedestrian lights."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from support import sumo_example

CORRIDOR_NET = "tools/game/corridor/corridor.net.xml"  # three traffic lights on one road
GRID6_NET = "tools/game/grid6/grid6.net.xml"  # six traffic lights, no left turns anywhere
RILSA_NET = "tools/sumolib/scenario/scenarios/RiLSA1BothTLS/rilsa1both.net.xml"  # 1 junction + 4 pedestrian lights


def _upload(client: TestClient, relative: str) -> dict[str, Any]:
    path = sumo_example(relative)
    response = client.post("/api/intersections/upload",
                           files={"file": (path.name, path.read_bytes(), "application/xml")})
    assert response.status_code == 200, response.text
    return response.json()


@pytest.fixture(scope="module")
def corridor(client: TestClient) -> dict[str, Any]:
    return _upload(client, CORRIDOR_NET)


def test_the_junctions_of_a_corridor(client: TestClient, corridor: dict[str, Any]) -> None:
    junctions = corridor["junctions"]
    assert [j["id"] for j in junctions] == ["gneJ11", "gneJ10", "gneJ12"], "the default first, then nearest it"
    assert [j["default"] for j in junctions] == [True, False, False]
    assert corridor["junction"] == "gneJ11" and corridor["junctions_not_listed"] == 0
    assert all(j["readable"] and j["approaches"] == 4 and j["reason"] is None for j in junctions)
    # the geometry of the default and the upload's answer list the same junctions
    geometry = client.get(f"/api/intersections/uploads/{corridor['id']}").json()
    assert geometry["junctions"] == junctions and geometry["junction"] == "gneJ11"


def test_another_junction_is_read_everywhere(client: TestClient, corridor: dict[str, Any]) -> None:
    base = f"/api/intersections/uploads/{corridor['id']}"
    west = client.get(base, params={"junction": "gneJ10"}).json()
    assert west["junction"] == "gneJ10" and west["center"][0] < corridor["center"][0] - 100
    west_approaches = {a["id"] for a in west["approaches"]}
    assert west_approaches.isdisjoint(a["id"] for a in corridor["approaches"])
    assert set(west["tasks"]) == west_approaches
    approach = west["approaches"][0]["id"]
    paths = client.get(f"{base}/paths", params={"task": "left", "junction": "gneJ10", "approach": approach})
    assert paths.status_code == 200, paths.text
    lanes = {lane["id"] for a in west["approaches"] for lane in a["entrance_lanes"]}
    assert paths.json() and all(p["entrance_lane"] in lanes for p in paths.json())
    # the default junction has no such approach: the paths route says so
    assert client.get(f"{base}/paths", params={"task": "left", "approach": approach}).status_code == 422
    lanes_check = client.get(f"{base}/internal-lanes", params={"junction": "gneJ10"}).json()
    assert {m["approach"] for m in lanes_check["movements"]} <= west_approaches


@pytest.mark.parametrize("suffix", ["", "/paths?task=left", "/internal-lanes"])
def test_an_unknown_junction_names_the_field(client: TestClient, corridor: dict[str, Any], suffix: str,
                                             field_named: Any) -> None:
    sep = "&" if "?" in suffix else "?"
    response = client.get(f"/api/intersections/uploads/{corridor['id']}{suffix}{sep}junction=atlantis")
    assert field_named(response, "query", "junction")
    message = response.json()["detail"][0]["msg"]
    assert "'atlantis' does not exist" in message and "gneJ10" in message
    assert message.startswith("corridor.net.xml:"), "the server's own path is not shown"


def test_tasks_offered_are_the_tasks_with_paths(client: TestClient) -> None:
    grid = _upload(client, GRID6_NET)
    assert len(grid["junctions"]) == 6 and all(j["readable"] for j in grid["junctions"])
    base = f"/api/intersections/uploads/{grid['id']}"
    picked = next(j["id"] for j in grid["junctions"] if not j["default"])
    geometry = client.get(base, params={"junction": picked}).json()
    assert geometry["tasks"] and all(tasks == ["straight", "right"] for tasks in geometry["tasks"].values())
    for approach, tasks in geometry["tasks"].items():
        for task in ("left", "straight", "right"):
            response = client.get(f"{base}/paths", params={"task": task, "approach": approach, "junction": picked})
            assert (response.status_code == 200) == (task in tasks), (approach, task, response.text)


def test_a_junction_the_reader_cannot_use_is_listed_with_its_reason(client: TestClient, field_named: Any) -> None:
    rilsa = _upload(client, RILSA_NET)
    by_id = {j["id"]: j for j in rilsa["junctions"]}
    assert by_id["0"]["default"] and by_id["0"]["readable"]
    light = by_id["ea"]
    assert not light["readable"] and "at least 3 are needed" in light["reason"]
    response = client.get(f"/api/intersections/uploads/{rilsa['id']}", params={"junction": "ea"})
    assert field_named(response, "query", "junction")
    assert response.json()["detail"][0]["msg"] == light["reason"]


def test_a_scenario_on_a_picked_junction(client: TestClient, corridor: dict[str, Any],
                                         tiny_scenario: dict[str, Any], field_named: Any) -> None:
    west = client.get(f"/api/intersections/uploads/{corridor['id']}", params={"junction": "gneJ10"}).json()
    approach = west["approaches"][0]["id"]
    scenario = {**tiny_scenario, "name": "corridor-west", "approach": approach,
                "intersection": {"net": corridor["net"], "junction": "gneJ10"}}
    created = client.post("/api/scenarios", json=scenario)
    assert created.status_code == 201, created.text
    # the same approach on the default junction: the save names the approach
    scenario["intersection"] = {"net": corridor["net"]}
    assert field_named(client.post("/api/scenarios", json=scenario), "approach")
    scenario["intersection"] = {"net": corridor["net"], "junction": "atlantis"}
    assert field_named(client.post("/api/scenarios", json=scenario), "intersection", "junction")


def test_the_catalogue_lists_its_one_junction(client: TestClient, field_named: Any) -> None:
    body = client.get("/api/intersections/a_single_lane").json()
    assert [(j["default"], j["readable"]) for j in body["junctions"]] == [(True, True)]
    assert set(body["tasks"]) == {a["id"] for a in body["approaches"]}
    assert all(tasks == ["left", "straight", "right"] for tasks in body["tasks"].values())
    again = client.get("/api/intersections/a_single_lane", params={"junction": body["junction_id"]})
    assert again.status_code == 200 and again.json()["junction_id"] == body["junction_id"]
    assert field_named(client.get("/api/intersections/a_single_lane", params={"junction": "atlantis"}),
                       "query", "junction")
