"""The intersection endpoints of the API, through FastAPI's test client."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from crossroads.api.main import create_app
from crossroads.settings import Settings

from .conftest import LOCAL_URL  # noqa: TID252


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> TestClient:
    settings = Settings(data_dir=tmp_path_factory.mktemp("data"))
    return TestClient(create_app(settings), base_url=LOCAL_URL)


def test_health(client: TestClient) -> None:
    body = client.get("/api/health").json()
    assert body["status"] == "ok"
    assert body["sumo"].startswith("1.28")


def test_catalogue_lists_the_six(client: TestClient) -> None:
    items = client.get("/api/intersections").json()
    assert len(items) >= 6
    assert all({"name", "description", "legs"} <= set(item) for item in items)


def test_geometry_for_drawing(client: TestClient) -> None:
    name = client.get("/api/intersections").json()[0]["name"]
    body = client.get(f"/api/intersections/{name}").json()
    assert body["name"] == name
    assert body["polygon"] and body["approaches"]
    for approach in body["approaches"]:
        assert approach["entrance_lanes"] and len(approach["stop_line"]) == 2
        assert all(lane["turns"] for lane in approach["entrance_lanes"])
    assert body["crossings"], "the catalogue's intersections have pedestrian crossings"


def test_paths_endpoint(client: TestClient) -> None:
    name = client.get("/api/intersections").json()[0]["name"]
    paths = client.get(f"/api/intersections/{name}/paths", params={"task": "left"}).json()
    assert paths and all(p["task"] == "left" and len(p["control_points"]) == 6 for p in paths)
    # SUMO's internal lane of each candidate's movement, for the preview: along it on a catalogue build
    assert all(len(p["sumo_internal_lane"]) >= 2 and p["sumo_offset_m"] < 0.05 for p in paths)


def test_unknown_intersection_is_404(client: TestClient) -> None:
    response = client.get("/api/intersections/atlantis")
    assert response.status_code == 404
    assert "atlantis" in response.json()["detail"]


@pytest.mark.parametrize(
    ("params", "field"),
    [({"task": "sideways"}, "task"), ({}, "task"), ({"task": "left", "rho": 1.5}, "rho")],
)
def test_bad_query_names_the_field(client: TestClient, params: dict, field: str) -> None:
    name = client.get("/api/intersections").json()[0]["name"]
    response = client.get(f"/api/intersections/{name}/paths", params=params)
    assert response.status_code == 422
    assert any(field in err["loc"] for err in response.json()["detail"])


def test_unknown_approach_names_the_field(client: TestClient) -> None:
    name = client.get("/api/intersections").json()[0]["name"]
    response = client.get(f"/api/intersections/{name}/paths", params={"task": "left", "approach": "nope"})
    assert response.status_code == 422
    assert response.json()["detail"].startswith("approach:")


def test_internal_lanes_of_a_catalogue_build_follow_the_paths(client: TestClient) -> None:
    body = client.get("/api/intersections/c_three_lane/internal-lanes").json()
    assert body["warning"] is None and body["max_m"] < 0.05
    assert len(body["movements"]) == 36 and not any(m["above_warning"] for m in body["movements"])
    assert client.get("/api/intersections/nowhere/internal-lanes").status_code == 404
