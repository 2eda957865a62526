"""The 3D viewers (viser servers) reached through the API's own port: HTTP and WebSocket proxying.

Each viewer is a ``viser.ViserServer`` bound to the loopback interface on a port of its own; the
browser never sees that port. The routes of :mod:`crossroads.api.routes.playback` and
:mod:`crossroads.api.routes.live` hand a viewer's page and its WebSocket on to it, so the 3D view
works wherever the studio does: behind a reverse proxy, through an SSH tunnel, in an iframe of the
studio page.

Viser's page connects its WebSocket to the URL it was loaded from (``ws[s]://<host>/<path>``, the
query and a trailing slash dropped), so a page served at ``…/view/`` connects to ``…/view``, which
:func:`proxy_websocket` serves. The page is one self-contained HTML file.
"""

from __future__ import annotations

import asyncio
import http.client
import logging
from typing import Any

from fastapi import WebSocket
from fastapi.responses import Response

from crossroads.settings import host_name, is_loopback

log = logging.getLogger(__name__)

LOOPBACK = "127.0.0.1"  # where every viewer listens: only this process reaches it
UPSTREAM_TIMEOUT_S = 10.0  # [s] a viewer that does not answer within this is taken as gone
MAX_MESSAGE_BYTES = 64 * 1024 * 1024  # viser sends meshes of a few MB; it allows 50 MB itself
PASSED_HEADERS = ("content-type", "content-encoding", "content-length", "cache-control", "etag",
                  "last-modified")
POLICY_VIOLATION = 1008  # WebSocket close codes
UPSTREAM_GONE = 1011


def fetch_page(port: int, path: str = "/", accept_encoding: str = "") -> Response:
    """``GET path`` from the viewer on ``port`` (loopback), answered as it came (gzip included).
    Call it from a worker thread (it blocks)."""
    conn = http.client.HTTPConnection(LOOPBACK, port, timeout=UPSTREAM_TIMEOUT_S)
    try:
        conn.request("GET", path or "/", headers={"Accept-Encoding": accept_encoding} if accept_encoding else {})
        upstream = conn.getresponse()
        body = upstream.read()
        headers = {k: v for k, v in upstream.getheaders() if k.lower() in PASSED_HEADERS}
        headers.pop("Content-Length", None)
        headers.setdefault("Cache-Control", "no-store")  # the page is the viewer's: it may be gone later
        return Response(body, status_code=upstream.status, headers=headers)
    except OSError as exc:
        return Response(f"the 3D viewer does not answer ({exc}); open it again from the studio",
                        status_code=502, media_type="text/plain")
    finally:
        conn.close()


def origin_allowed(websocket: WebSocket, allowed_hosts: tuple[str, ...] = ()) -> bool:
    """Whether the page opening this WebSocket is the studio's own (or not a browser at all).

    A WebSocket is not subject to the same-origin policy, and the viewer's socket takes input
    (the player's controls): a page elsewhere must not drive it. Same rule as the request guard
    for state-changing requests: the Origin names the Host the request reached, or the same port
    under another loopback name, or an allowed host."""
    origin = websocket.headers.get("origin")
    if origin is None:
        return True  # not a browser (a browser always sends Origin with a WebSocket)
    from urllib.parse import urlsplit

    host = websocket.headers.get("host", "")
    try:
        theirs = urlsplit(origin)
        ours = urlsplit(f"//{host}")
        their_name, our_name = host_name(theirs.hostname or ""), host_name(ours.hostname or "")
        their_port = theirs.port or {"http": 80, "https": 443}.get(theirs.scheme)
        our_port = ours.port or {"ws": 80, "wss": 443, "http": 80, "https": 443}.get(
            websocket.url.scheme)
    except ValueError:
        return False
    if not their_name or their_port != our_port:
        return False
    return (their_name == our_name or (is_loopback(their_name) and is_loopback(our_name))
            or their_name in {host_name(h) for h in allowed_hosts})


async def proxy_websocket(websocket: WebSocket, port: int, *, allowed_hosts: tuple[str, ...] = (),
                          on_open: Any = None, on_close: Any = None) -> None:
    """Join the browser's WebSocket to the viewer's on ``port`` until either side closes.

    The browser's subprotocol (viser's version check, ``viser-v<version>``) is passed on, and the
    one the viewer picks is the one accepted. ``on_open``/``on_close``: called (no arguments)
    when the pair is joined and when it ends, e.g. to count a viewer's open tabs."""
    from websockets.asyncio.client import connect
    from websockets.exceptions import InvalidHandshake
    from websockets.typing import Subprotocol

    if not origin_allowed(websocket, allowed_hosts):
        await websocket.close(code=POLICY_VIOLATION)
        return
    protocols = [Subprotocol(p) for p in websocket.scope.get("subprotocols", [])]
    try:
        upstream = await connect(f"ws://{LOOPBACK}:{port}/", subprotocols=protocols or None,
                                 compression=None, proxy=None, max_size=MAX_MESSAGE_BYTES,
                                 open_timeout=UPSTREAM_TIMEOUT_S)
    except (OSError, InvalidHandshake, asyncio.TimeoutError) as exc:
        log.info("viewer on port %s unreachable: %s", port, exc)
        await websocket.close(code=UPSTREAM_GONE)
        return
    await websocket.accept(subprotocol=upstream.subprotocol)
    if on_open is not None:
        on_open()

    async def down() -> None:  # viewer → browser
        async for message in upstream:
            if isinstance(message, bytes):
                await websocket.send_bytes(message)
            else:
                await websocket.send_text(message)

    async def up() -> None:  # browser → viewer
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                return
            if message.get("bytes") is not None:
                await upstream.send(message["bytes"])
            elif message.get("text") is not None:
                await upstream.send(message["text"])

    tasks = [asyncio.create_task(down()), asyncio.create_task(up())]
    try:
        await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
    finally:
        # first what needs no waiting: under a cancelled scope (a server shutting down) every
        # await below may raise again
        if on_close is not None:
            on_close()
        for task in tasks:
            task.cancel()
        try:
            await asyncio.gather(*tasks, return_exceptions=True)
            await upstream.close()
            await websocket.close()
        except Exception:  # noqa: BLE001 - either side is gone already
            pass
