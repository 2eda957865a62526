"""Who may drive the API: the Host it is reached by (DNS rebinding), the Origin of state-changing
requests (another web page), the access token of a server listening beyond loopback, and GETs
that change nothing."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from crossroads.api.main import create_app
from crossroads.settings import Settings
from crossroads.store import crud

from .conftest import LOCAL_URL  # noqa: TID252

TOKEN = "a-test-token-of-32-characters-xx"


def _queued_batch(client: TestClient, scenario: dict[str, Any]) -> int:
    """A batch stored as queued that no runner of this process holds (as a previous server left it)."""
    store = client.app.state.store
    scenario_id = client.post("/api/scenarios", json=scenario).json()["id"]
    with store.session() as s:
        row = crud.get_scenario(session=s, scenario_id=scenario_id)
        policy = crud.get_or_create_policy(session=s, ref="rule")
        return crud.create_batch(session=s, scenario=row, policy=policy, runs=2).id


@pytest.mark.parametrize("host", ["evil.example", "127.0.0.1.nip.io", "localhost.evil.example:8000", ""])
def test_a_foreign_host_reaches_nothing(client: TestClient, host: str) -> None:
    """A page whose DNS name was rebound to 127.0.0.1 sends its own name in Host: refused, reads
    included, the page too."""
    for path in ("/api/scenarios", "/api/health", "/"):
        response = client.get(path, headers={"host": host})
        assert response.status_code == 421, (path, response.text)
        assert "--allowed-host" in response.json()["detail"]


@pytest.mark.parametrize("host", ["127.0.0.1", "localhost:8000", "[::1]:8000", "LOCALHOST", "127.0.0.1:1"])
def test_loopback_names_are_answered(client: TestClient, host: str) -> None:
    assert client.get("/api/health", headers={"host": host}).status_code == 200


def test_a_cross_site_post_changes_nothing(client: TestClient, tiny_scenario: dict[str, Any]) -> None:
    """The hostile page's own tricks: a text/plain POST (no preflight) to cancel, a multipart upload,
    a JSON POST; from another origin, from ``null``, or marked cross-site without an Origin."""
    batch_id = _queued_batch(client, {**tiny_scenario, "name": "guard-queued"})
    uploads_before = client.get("/api/intersections/uploads").headers["x-total-count"]
    scenarios_before = client.get("/api/scenarios").headers["x-total-count"]
    hostile = [{"origin": "http://evil.example"}, {"origin": "null"}, {"origin": "http://127.0.0.1:9999"},
               {"origin": "http://localhost.evil.example"}, {"sec-fetch-site": "cross-site"},
               {"sec-fetch-site": "same-site"}]
    for headers in hostile:
        cancel = client.post(f"/api/batches/{batch_id}/cancel", content=b"x",
                             headers={**headers, "content-type": "text/plain"})
        assert cancel.status_code == 403, (headers, cancel.text)
        upload = client.post("/api/intersections/upload", headers=headers,
                             files={"file": ("x.net.xml", b"<net/>", "application/xml")})
        assert upload.status_code == 403, (headers, upload.text)
        assert client.post("/api/scenarios", json={**tiny_scenario, "name": "guard-x"},
                           headers=headers).status_code == 403
        assert client.delete("/api/scenarios/1", headers=headers).status_code == 403
    assert client.get(f"/api/batches/{batch_id}").json()["status"] == "queued"
    assert client.get("/api/intersections/uploads").headers["x-total-count"] == uploads_before
    assert client.get("/api/scenarios").headers["x-total-count"] == scenarios_before


def test_the_studios_own_page_may_post(client: TestClient, tiny_scenario: dict[str, Any]) -> None:
    """Same origin (what the served page sends), the same port under another loopback name, and
    a client that is no browser (no Origin at all) may change things."""
    for i, headers in enumerate([{"origin": "http://127.0.0.1", "sec-fetch-site": "same-origin"},
                                 {"origin": "http://localhost:8000", "host": "127.0.0.1:8000"},
                                 {"origin": "http://[::1]:8000", "host": "localhost:8000"},
                                 {}]):
        response = client.post("/api/scenarios", json={**tiny_scenario, "name": f"guard-ok-{i}"}, headers=headers)
        assert response.status_code == 201, (headers, response.text)
    batch_id = _queued_batch(client, {**tiny_scenario, "name": "guard-own-cancel"})
    cancel = client.post(f"/api/batches/{batch_id}/cancel", headers={"origin": "http://127.0.0.1"})
    assert cancel.status_code == 202 and cancel.json()["status"] == "cancelled"


def test_gets_change_nothing(client: TestClient, finished_batch: dict[str, Any]) -> None:
    """GET /playback/... starts no player: it answers a page that POSTs (from the studio's origin)."""
    from crossroads.api.routes.playback import _PLAYERS

    batch_id = finished_batch["id"]
    before = dict(_PLAYERS.servers)
    page = client.get(f"/api/playback/{batch_id}/0", follow_redirects=False)
    assert page.status_code == 200 and 'method="post"' in page.text
    assert dict(_PLAYERS.servers) == before
    assert client.get(f"/api/playback/{batch_id}/99", follow_redirects=False).status_code == 404
    refused = client.post(f"/api/playback/{batch_id}/0", headers={"origin": "http://evil.example"})
    assert refused.status_code == 403 and dict(_PLAYERS.servers) == before


@pytest.fixture(scope="module")
def public(tmp_path_factory: pytest.TempPathFactory) -> TestClient:
    """An app that listens beyond loopback (its lifespan is not started: the guard answers first)."""
    settings = Settings(data_dir=tmp_path_factory.mktemp("public"), host="0.0.0.0", port=8000, token=TOKEN,
                        allowed_hosts=("studio.lan",))
    return TestClient(create_app(settings), base_url=LOCAL_URL)


def test_beyond_loopback_a_token_is_required(public: TestClient) -> None:
    refused = public.get("/api/health")
    assert refused.status_code == 401 and "token" in refused.json()["detail"]
    assert refused.headers["www-authenticate"] == "Bearer"
    assert public.get("/api/health", headers={"authorization": "Bearer wrong-token-wrong-token"}).status_code == 401
    assert public.get("/api/health", headers={"authorization": f"Bearer {TOKEN}"}).status_code == 200
    assert public.get("/api/health", headers={"host": "studio.lan:8000",
                                              "authorization": f"Bearer {TOKEN}"}).status_code == 200
    assert public.get("/openapi.json").status_code == 401
    # listening on every interface, it answers to this machine's own name too, and to nothing else
    import socket

    bearer = {"authorization": f"Bearer {TOKEN}"}
    assert public.get("/api/health", headers={**bearer, "host": f"{socket.gethostname()}:8000"}).status_code == 200
    assert public.get("/api/health", headers={**bearer, "host": "rebound.example:8000"}).status_code == 421


def test_the_printed_url_sets_a_strict_cookie(public: TestClient) -> None:
    """/?token=… (the URL `serve` prints) answers a redirect that drops the token from the address
    bar and sets a SameSite=Strict cookie, which then opens the API to the page."""
    wrong = public.get("/?token=nope", follow_redirects=False)
    assert wrong.status_code == 401
    opened = public.get(f"/?token={TOKEN}&tab=2", follow_redirects=False)
    assert opened.status_code == 303 and opened.headers["location"] == "/?tab=2"
    cookie = opened.headers["set-cookie"]
    assert cookie.startswith(f"crossroads_token_8000={TOKEN}") and "SameSite=Strict" in cookie and "HttpOnly" in cookie
    with_cookie = public.get("/api/health", headers={"cookie": f"crossroads_token_8000={TOKEN}"})
    assert with_cookie.status_code == 200
    # the cookie does not let another page change anything
    post = public.post("/api/batches/1/cancel", headers={"cookie": f"crossroads_token_8000={TOKEN}",
                                                         "origin": "http://evil.example"})
    assert post.status_code == 403


def test_no_public_server_without_a_token(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="without an access token"):
        create_app(Settings(data_dir=tmp_path, host="0.0.0.0"))
    with pytest.raises(ValueError, match="letters, digits"):
        Settings(data_dir=tmp_path, token="has;a semicolon-and-more")
    assert Settings(data_dir=tmp_path, host="::1").public is False
    assert Settings(data_dir=tmp_path, host="192.168.1.5", token=TOKEN).public is True
    assert Settings(data_dir=tmp_path, allowed_hosts="a.lan, B.lan.").allowed_hosts == ("a.lan", "b.lan")


def test_serve_warns_and_makes_a_token_when_public(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """`serve --host 0.0.0.0` says what it exposes and prints the URL with a generated token (the
    server itself is not started here: uvicorn.run only records what it was given)."""
    import uvicorn
    from typer.testing import CliRunner

    from crossroads.cli import app

    served: list[Any] = []
    monkeypatch.setattr(uvicorn, "run", lambda application, **kw: served.append((application, kw)))
    monkeypatch.setenv("CROSSROADS_DATA_DIR", str(tmp_path))
    monkeypatch.delenv("CROSSROADS_TOKEN", raising=False)
    result = CliRunner().invoke(app, ["serve", "--host", "0.0.0.0", "--port", "8123", "--allowed-host", "studio.lan"])
    assert result.exit_code == 0, result.output
    assert "WARNING: listening on 0.0.0.0" in result.output and "studio.lan" in result.output
    assert "3D viewers" in result.output
    settings = served[-1][0].state.settings
    token = settings.token.get_secret_value()
    assert len(token) >= 16 and f"http://0.0.0.0:8123/?token={token}" in result.output
    assert served[-1][1] == {"host": "0.0.0.0", "port": 8123, "log_level": "info", "timeout_graceful_shutdown": 5}

    given = CliRunner().invoke(app, ["serve", "--token", TOKEN])
    assert given.exit_code == 0 and "WARNING" not in given.output
    assert f"http://127.0.0.1:8000/?token={TOKEN}" in given.output
    local = CliRunner().invoke(app, ["serve"])
    assert local.exit_code == 0 and "token" not in local.output and "WARNING" not in local.output
    assert served[-1][0].state.settings.token is None
