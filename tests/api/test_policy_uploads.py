"""Uploaded ONNX policies: checked, listed with their hash, run in a batch by name, deleted."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from crossroads.api.routes import policy_uploads
from evaluation.test_onnx_policy import linear_policy

from .conftest import TINY_SCENARIO  # noqa: TID252


def _upload(client: TestClient, data: bytes, name: str = "linear", card: str | None = "a linear test policy",
            filename: str = "linear.onnx") -> Any:
    fields = {"name": name} | ({} if card is None else {"card": card})
    return client.post("/api/policies/upload", files={"file": (filename, data, "application/octet-stream")},
                       data=fields)


def _stored(data_dir: Path) -> list[str]:
    directory = data_dir / "policies"
    return sorted(p.name for p in directory.iterdir()) if directory.is_dir() else []


def test_an_uploaded_policy_is_listed_with_its_hash_run_in_a_batch_and_deleted(
        client: TestClient, data_dir: Path, wait_for: Any) -> None:
    data = linear_policy()
    response = _upload(client, data, name="linear-a")
    assert response.status_code == 201, response.text
    body = response.json()
    assert (body["name"], body["kind"], body["file"], body["shield"]) == ("linear-a", "onnx", "linear-a.onnx", False)
    assert body["sha256"] == hashlib.sha256(data).hexdigest()
    listed = {p["name"]: p for p in client.get("/api/policies").json()}
    assert listed["linear-a"]["sha256"] == body["sha256"] and listed["linear-a+shield"]["shield"]
    assert listed["linear-a"]["card"]["card"] == "a linear test policy"
    assert listed["linear-a"]["card"]["signature"]["state_width"] == 108
    uploads = {u["name"]: u for u in client.get("/api/policies/uploads").json()}
    assert uploads["linear-a"]["filename"] == "linear.onnx" and uploads["linear-a"]["size_bytes"] == len(data)

    started = client.post("/api/batches", json={"scenario": TINY_SCENARIO, "policy": "linear-a+shield",
                                                "runs": 1, "workers": 1, "traces": "none"})
    assert started.status_code == 202, started.text
    done = wait_for(started.json()["id"], ("done", "failed", "cancelled"))
    assert done["status"] == "done" and done["policy"] == "linear-a+shield", done

    assert client.delete("/api/policies/uploads/linear-a").status_code == 204
    assert "linear-a" not in {p["name"] for p in client.get("/api/policies").json()}
    assert "linear-a.onnx" not in _stored(data_dir)
    assert client.delete("/api/policies/uploads/linear-a").status_code == 404
    assert client.get(f"/api/batches/{done['id']}").json()["policy"] == "linear-a+shield"  # results stay


@pytest.mark.parametrize(("kwargs", "status", "field", "words"), [
    ({"data": linear_policy(width=100)}, 422, "file", "the IDC state is (batch, 108 or 120)"),
    ({"data": b"\x08\x07garbage"}, 422, "file", "not an ONNX model"),
    ({"data": b""}, 422, "file", "empty"),
    ({"name": "rule"}, 409, "name", "a policy named 'rule' exists"),
    ({"name": "fake"}, 409, "name", "a policy named 'fake' exists"),
    ({"name": "../evil"}, 422, "name", "letters, digits"),
    ({"name": "x+shield"}, 422, "name", "letters, digits"),
    ({"card": None}, 422, "card", "missing"),
    ({"card": "   "}, 422, "card", "give a short card"),
    ({"card": "c" * 2001}, 422, "card", "at most 2000"),
])
def test_a_bad_upload_is_refused_naming_the_field_and_nothing_is_stored(
        client: TestClient, data_dir: Path, kwargs: dict[str, Any], status: int, field: str, words: str) -> None:
    before = _stored(data_dir)
    args = {"data": linear_policy(), "name": "refused"} | kwargs
    response = _upload(client, **args)
    assert response.status_code == status, response.text
    detail = response.json()["detail"][0]
    assert detail["loc"] == ["body", field] and words in detail["msg"], detail
    assert _stored(data_dir) == before


def test_size_limit_and_form(client: TestClient, data_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(policy_uploads, "MAX_POLICY_BYTES", 1000)
    big = _upload(client, linear_policy(), name="big")
    assert big.status_code == 413 and "above the limit" in big.json()["detail"][0]["msg"]
    plain = client.post("/api/policies/upload", json={"name": "x"})
    assert plain.status_code == 422 and "multipart/form-data" in plain.json()["detail"][0]["msg"]
    assert client.delete("/api/policies/uploads/-x").status_code == 422  # not a name the upload gives
    assert client.delete(f"/api/policies/uploads/{'a' * 65}").status_code == 422
    assert client.delete("/api/policies/uploads/no-such-policy").status_code == 404


def test_a_name_is_taken_once(client: TestClient) -> None:
    assert _upload(client, linear_policy(), name="twice").status_code == 201
    again = _upload(client, linear_policy(value=False), name="twice")
    assert again.status_code == 409
    assert client.delete("/api/policies/uploads/twice").status_code == 204
