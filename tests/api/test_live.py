"""Live runs: invalid requests are 422s naming the field (and start nothing); a run answers at
once with the viewer's URL, runs its episode in a child process while the viewer draws it, and
ends with the episode's result; a waiting run can be stopped; beyond the limit, a 429."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from crossroads.api.live import LiveRun, LiveRuns

from .conftest import wait_for_status  # noqa: TID252

LIVE_TIMEOUT_S = 90.0
FINAL = ("done", "failed", "stopped")


@pytest.fixture
def live(client: TestClient, monkeypatch: pytest.MonkeyPatch) -> Iterator[LiveRuns]:
    runs: LiveRuns = client.app.state.live
    monkeypatch.setattr(runs, "viewer_wait_s", 0.2)  # no tab opens in these tests: start at once
    yield runs


def _wait(client: TestClient, run_id: int, statuses: tuple[str, ...]) -> dict[str, Any]:
    return wait_for_status(client, f"/api/live/{run_id}", statuses, LIVE_TIMEOUT_S)


@pytest.mark.parametrize(("body", "loc"), [
    ({"scenario_id": 1, "seed": -1}, ("seed",)),
    ({"scenario_id": 1, "seed": 2**31}, ("seed",)),                 # above SUMO's C int
    ({"scenario_id": 1, "seed": "7"}, ("seed",)),
    ({"scenario_id": 1, "speed": -1}, ("speed",)),
    ({"scenario_id": 1, "speed": 100}, ("speed",)),
    ({"scenario_id": 1, "policy": "nonsense"}, ("policy",)),
    ({"scenario_id": 1, "policy": "../models/x.pt"}, ("policy",)),
    ({"scenario_id": 1, "colour": "red"}, ("colour",)),
    ({"policy": "rule"}, ("scenario_id",)),                          # no scenario
    ({"scenario_id": 987654}, ("scenario_id",)),
    ({"scenario_id": 1, "scenario": {"version": 1}}, ("scenario_id",)),
    ({"scenario": {"version": 1, "name": "x", "intersection": "a_single_lane", "task": "up"}},
     ("scenario", "task")),
    ({"scenario": {"version": 1, "name": "x", "intersection": "a_single_lane", "task": "left",
                   "approach": "nowhere"}}, ("scenario", "approach")),
    ({"scenario": {"version": 1, "name": "x", "intersection": "a_single_lane", "task": "left",
                   "ego": {"entrance_lane": "nope"}}}, ("scenario", "ego", "entrance_lane")),
    ({"scenario": {"version": 1, "name": "x", "intersection": "a_single_lane", "task": "left",
                   "lights": {"phase": 9}}}, ("scenario", "lights", "phase")),
])
def test_invalid_live_run_names_the_field(client: TestClient, live: LiveRuns, tiny_scenario: dict[str, Any],
                                          field_named: Any, body: dict[str, Any], loc: tuple[str, ...]) -> None:
    if body.get("scenario_id") == 1:
        body = {**body, "scenario_id": client.post("/api/scenarios", json=tiny_scenario).json()["id"]}
    before = len(live.list())
    response = client.post("/api/live", json=body)
    assert field_named(response, *loc), response.json()
    assert len(live.list()) == before, "nothing started"


def test_unknown_live_run(client: TestClient) -> None:
    assert client.get("/api/live/999999").status_code == 404
    assert client.post("/api/live/999999/stop").status_code == 404
    assert client.get("/api/live/abc").status_code == 422


def test_a_live_run_shows_its_episode_and_ends_with_the_result(
        client: TestClient, live: LiveRuns, tiny_scenario: dict[str, Any]) -> None:
    sid = client.post("/api/scenarios", json=tiny_scenario).json()["id"]
    started = time.monotonic()
    response = client.post("/api/live", json={"scenario_id": sid, "seed": 11, "speed": 0})
    assert response.status_code == 202, response.text
    assert time.monotonic() - started < 5.0, "the episode runs outside the request"
    body = response.json()
    assert body["status"] in ("starting", "waiting", "running") and body["seed"] == 11
    assert body["url"] == f"/api/live/{body['id']}/view/", "reached through the API's own port"
    page = client.get(body["url"])
    assert page.status_code == 200 and "<html" in page.text.lower(), "the viewer answers"
    assert live.get(body["id"]).server.get_host() == "127.0.0.1", "the viewer listens on loopback only"

    ended = _wait(client, body["id"], FINAL)
    assert ended["status"] == "done", ended
    assert ended["result"]["outcome"] in ("passed", "collision", "red_light", "off_road", "timeout")
    assert ended["result"]["seed"] == 11 and ended["frames"] >= 1
    assert live.get(body["id"]).viewer.frames_shown == ended["frames"]
    assert body["id"] in [r["id"] for r in client.get("/api/live").json()]


def test_stop_a_waiting_run_and_the_limit(client: TestClient, live: LiveRuns, tiny_scenario: dict[str, Any],
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(live, "viewer_wait_s", 60.0)  # it waits for a tab that never comes
    monkeypatch.setattr(live, "max_active", 1)
    first = client.post("/api/live", json={"scenario": tiny_scenario})
    assert first.status_code == 202, first.text
    run_id = first.json()["id"]
    busy = client.post("/api/live", json={"scenario": tiny_scenario})
    assert busy.status_code == 429 and "at most 1" in busy.json()["detail"]

    _wait(client, run_id, ("waiting",) + FINAL)
    stopping = client.post(f"/api/live/{run_id}/stop")
    assert stopping.status_code == 202
    assert _wait(client, run_id, FINAL)["status"] == "stopped"
    assert client.get(f"/api/live/{run_id}").json()["frames"] == 0, "stopped before it began"


class _Pipe:
    """The receiving end of a child's pipe that has sent ``messages`` and closed."""

    def __init__(self, messages: list[tuple[str, Any]]) -> None:
        self.messages = list(messages)

    def poll(self, _timeout: float = 0.0) -> bool:
        return True  # a message, or the end of the pipe, is always ready

    def recv(self) -> Any:
        if not self.messages:
            raise EOFError
        return self.messages.pop(0)


class _Stub:
    """Whatever a LiveRun holds that this test does not look at."""

    exitcode = 0
    frames_shown = 0

    def join(self, _timeout: float | None = None) -> None: ...
    def is_alive(self) -> bool: return False
    def get_port(self) -> int: return 1
    def show_frame(self, _frame: Any) -> None: self.frames_shown += 1


@pytest.mark.parametrize(("messages", "status"), [
    ([("frame", {"t": 0.0}), ("frame", {"t": 0.1}), ("result", {"outcome": "passed", "time_s": 0.2})], "done"),
    ([("frame", {"t": 0.0}), ("error", "RuntimeError: boom")], "failed"),
    ([("frame", {"t": 0.0})], "failed"),   # died without its last word
])
def test_the_last_message_before_the_pipe_closes_counts(messages: list[tuple[str, Any]], status: str) -> None:
    stub = _Stub()
    run = LiveRun(1, "s", "rule", 0, 0.0, server=stub, process=stub, conn=_Pipe(messages),
                  stop_event=threading.Event(), go=threading.Event(), status="running", viewer=stub)
    LiveRuns()._receive(run)
    assert run.status == status, run.error
    assert run.frames == stub.frames_shown == 1, "the frames that piled up: only the newest drawn"
    if status == "done":
        assert run.result == {"outcome": "passed", "time_s": 0.2}
    elif messages[-1][0] == "frame":
        assert "without a result" in (run.error or "")
