"""The API against a temporary SQLite store: one app per test session (the store is migrated once),
a models directory with a fake checkpoint and its card, and one tiny batch shared by the tests
that need a finished one."""

from __future__ import annotations

import copy
import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from crossroads.api.deps import ApiOptions
from crossroads.api.main import create_app
from crossroads.settings import Settings

UPLOAD_LIMIT_BYTES = 256 * 1024  # small, so "too big" is cheap to make
LOCAL_URL = "http://127.0.0.1"  # the API answers to localhost names only (not the test client's "testserver")
BATCH_TIMEOUT_S = 120.0

# A short, quiet episode (SUMO warm-up 5 s, 5 s of ego time, little traffic).
TINY_SCENARIO: dict[str, Any] = {
    "version": 1, "name": "api-tiny-left", "intersection": "a_single_lane", "task": "left",
    "traffic": {"vehicles_per_hour": 100, "cyclists_per_hour": 0, "pedestrians_per_hour": 0},
    "warmup_s": 5.0, "timeout_s": 5.0, "runs": 2, "seed": 3,
}


@pytest.fixture(scope="session")
def data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("api-data")


@pytest.fixture(scope="session")
def models_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("models")
    (path / "fake.pt").write_bytes(b"not really a checkpoint")
    (path / "fake.card.json").write_text(json.dumps({"algorithm": "APG", "iterations": 1}))
    return path


@pytest.fixture(scope="session")
def client(data_dir: Path, models_dir: Path) -> Iterator[TestClient]:
    settings = Settings(data_dir=data_dir)
    options = ApiOptions(upload_max_bytes=UPLOAD_LIMIT_BYTES, models_dir=models_dir)
    with TestClient(create_app(settings, options), base_url=LOCAL_URL) as test_client:
        yield test_client


def wait_for_status(client: TestClient, url: str, statuses: tuple[str, ...], timeout_s: float) -> dict[str, Any]:
    """Poll GET ``url`` until the body's ``status`` is one of ``statuses``; fail after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while True:
        body = client.get(url).json()
        if body["status"] in statuses:
            return body
        assert time.monotonic() < deadline, f"{url} still {body['status']}"
        time.sleep(0.1)


def _wait_for(client: TestClient, batch_id: int, statuses: tuple[str, ...],
             timeout_s: float = BATCH_TIMEOUT_S) -> dict[str, Any]:
    """Poll GET /batches/{id} until its status is one of ``statuses``."""
    return wait_for_status(client, f"/api/batches/{batch_id}", statuses, timeout_s)


def _field_named(response: Any, *parts: str | int) -> bool:
    """Whether a 422's detail names a field whose location ends with ``parts``."""
    assert response.status_code == 422, response.text
    n = len(parts)
    return any(tuple(err["loc"][-n:]) == parts for err in response.json()["detail"])


@pytest.fixture(scope="session")
def wait_for(client: TestClient) -> Any:
    """``wait_for(batch_id, statuses, timeout_s=...)`` → the batch's body once in one of them."""
    return lambda batch_id, statuses, timeout_s=BATCH_TIMEOUT_S: _wait_for(client, batch_id, statuses,
                                                                          timeout_s)


@pytest.fixture(scope="session")
def field_named() -> Any:
    """``field_named(response, *loc_tail)``: a 422 naming that field."""
    return _field_named


@pytest.fixture
def tiny_scenario() -> dict[str, Any]:
    return copy.deepcopy(TINY_SCENARIO)


@pytest.fixture(scope="session")
def tiny_batch(client: TestClient) -> int:
    """A tiny batch (2 runs, 1 worker, every trace kept), started once; returns its id."""
    response = client.post("/api/batches", json={"scenario": TINY_SCENARIO, "policy": "rule",
                                                 "runs": 2, "workers": 1, "traces": "all"})
    assert response.status_code == 202, response.text
    return response.json()["id"]


@pytest.fixture(scope="session")
def finished_batch(client: TestClient, tiny_batch: int) -> dict[str, Any]:
    body = _wait_for(client, tiny_batch, ("done", "failed", "cancelled"))
    assert body["status"] == "done", body
    return body
