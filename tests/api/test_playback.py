"""The 3D playback through the API's own port: the player's page and WebSocket handed on to a viser
server on loopback, the studio's origin only, idle players shut down, a bounded number running."""

from __future__ import annotations

import time
from typing import Any

import pytest
import viser
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from crossroads.api.routes.playback import _PLAYERS, Players

PROTOCOL = f"viser-v{viser.__version__}"
OWN_ORIGIN = {"origin": "http://127.0.0.1"}
WS_BASE = "ws://127.0.0.1"  # the test client's WebSockets ignore its base URL


def _open(client: TestClient, batch_id: int, run_index: int = 0) -> dict[str, Any]:
    response = client.post(f"/api/playback/{batch_id}/{run_index}")
    assert response.status_code == 200, response.text
    return response.json()


def test_the_player_is_served_through_the_api(client: TestClient, finished_batch: dict[str, Any]) -> None:
    batch_id = finished_batch["id"]
    opened = _open(client, batch_id)
    assert opened["url"] == f"/api/playback/{batch_id}/0/view/"
    server = _PLAYERS.peek((batch_id, 0))
    assert server is not None and server.server.get_host() == "127.0.0.1", "the player listens on loopback only"
    assert _open(client, batch_id)["url"] == opened["url"] and _PLAYERS.peek((batch_id, 0)) is server, "reused"

    page = client.get(opened["url"])
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert "<html" in page.text.lower() and len(page.text) > 10_000, "viser's own page"
    assert client.get(opened["url"].rstrip("/"), follow_redirects=False).status_code == 307
    # a plain link goes to the running player
    link = client.get(f"/api/playback/{batch_id}/0", follow_redirects=False)
    assert link.status_code == 303 and link.headers["location"] == opened["url"]

    # viser's client connects to the page's own URL without the slash, with its version as subprotocol
    with client.websocket_connect(WS_BASE + opened["url"].rstrip("/"), subprotocols=[PROTOCOL], headers=OWN_ORIGIN) as ws:
        assert ws.accepted_subprotocol == PROTOCOL
        first = ws.receive_bytes()  # the scene and the player's GUI, msgpack
        assert len(first) > 0
        assert _PLAYERS.in_use((batch_id, 0)), "an open tab: never idle"
        assert (batch_id, 0) not in _PLAYERS.reap(now=time.monotonic() + _PLAYERS.idle_s + 1)
        ws.close()  # the tab goes away: the proxy ends, the player's socket closes
        deadline = time.monotonic() + 10
        while _PLAYERS.in_use((batch_id, 0)) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _PLAYERS.in_use((batch_id, 0)), "the tab's socket closed"


def test_another_sites_page_may_not_drive_a_player(client: TestClient, finished_batch: dict[str, Any]) -> None:
    url = _open(client, finished_batch["id"])["url"].rstrip("/")
    for origin in ("http://evil.example", "http://127.0.0.1:9999", "null"):
        with pytest.raises(WebSocketDisconnect) as refused:
            with client.websocket_connect(WS_BASE + url, subprotocols=[PROTOCOL], headers={"origin": origin}) as ws:
                ws.receive_bytes()
        assert refused.value.code == 1008, origin


def test_no_player_no_socket_and_the_page_reopens_it(client: TestClient, finished_batch: dict[str, Any]) -> None:
    batch_id = finished_batch["id"]
    _open(client, batch_id, 1)
    assert (batch_id, 1) in _PLAYERS.reap(now=time.monotonic() + _PLAYERS.idle_s + 1), "idle: shut down"
    assert _PLAYERS.peek((batch_id, 1)) is None
    page = client.get(f"/api/playback/{batch_id}/1/view/")
    assert page.status_code == 200 and 'method="post"' in page.text, "a reload opens it again (by a POST)"
    assert _PLAYERS.peek((batch_id, 1)) is None, "a GET starts nothing"
    with pytest.raises(WebSocketDisconnect):
        with client.websocket_connect(f"{WS_BASE}/api/playback/{batch_id}/1/view", subprotocols=[PROTOCOL],
                                      headers=OWN_ORIGIN) as ws:
            ws.receive_bytes()
    # the form the page submits opens the player and goes to it
    opened = client.post(f"/api/playback/{batch_id}/1", data={}, headers={**OWN_ORIGIN,
                         "content-type": "application/x-www-form-urlencoded"}, follow_redirects=False)
    assert opened.status_code == 303 and opened.headers["location"] == f"/api/playback/{batch_id}/1/view/"
    assert _PLAYERS.peek((batch_id, 1)) is not None


class _Server:
    """What Players looks at of a PlaybackServer: its tabs, and whether it was stopped."""

    def __init__(self) -> None:
        self.clients: dict[int, object] = {}
        self.stopped = False
        self.server = self

    def get_clients(self) -> dict[int, object]:
        return self.clients

    def stop(self) -> None:
        self.stopped = True


def test_players_are_bounded_and_the_idle_ones_stop() -> None:
    players = Players(max_servers=2, idle_s=60.0)
    try:
        a, b, c = _Server(), _Server(), _Server()
        players.get((1, 0), lambda: a)
        players.get((1, 1), lambda: b)
        players.get((1, 0), lambda: pytest.fail("reused, not started again"))  # (1, 1) is now the oldest
        players.get((1, 2), lambda: c)
        assert b.stopped and not a.stopped and set(players.servers) == {(1, 0), (1, 2)}
        a.clients[0] = object()  # a tab has (1, 0) open: never idle
        now = time.monotonic()
        assert players.reap(now + 30) == []
        assert players.reap(now + 61) == [(1, 2)] and c.stopped and not a.stopped
        a.clients.clear()
        assert players.reap(now + 61 + 59) == [] and players.reap(now + 61 + 61) == [(1, 0)]
        assert a.stopped and not players.servers
    finally:
        players.stop_all()
