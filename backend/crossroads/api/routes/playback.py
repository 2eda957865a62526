"""Playback: a stored episode in the 3D view, served through the API's own port.

``POST /playback/{batch_id}/{run_index}`` starts (or reuses) a player for the episode's trace (a
viser :class:`~crossroads.viz.playback.PlaybackServer` on a loopback port no browser sees) and
answers the URL of its page, ``/api/playback/{batch_id}/{run_index}/view/`` (JSON; a browser's
form submission is redirected there instead, 303). That page and its WebSocket
(``…/view``) are handed on to the player by :mod:`crossroads.api.viewer_proxy`, so the view works
behind a reverse proxy or an SSH tunnel and fits in an iframe of the studio page.

``GET`` on the episode's path, or on its page while no player runs, starts nothing (a GET never
changes anything): it answers a small page that submits that POST from the studio's own origin,
so a plain link (or a reload after the player was shut down) opens the playback.

At most ``MAX_SERVERS`` players run at once (the least recently used one is stopped to make
room), and a player no tab has had open for ``IDLE_S`` is shut down.
"""

from __future__ import annotations

import atexit
import threading
import time
from collections import OrderedDict
from pathlib import Path
from typing import Any

from fastapi import APIRouter, HTTPException, Request, WebSocket
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from crossroads.api.deps import SessionDep, SettingsDep
from crossroads.api.params import BatchId, RunIndex
from crossroads.api.viewer_proxy import LOOPBACK, fetch_page, proxy_websocket
from crossroads.store import crud

router = APIRouter(prefix="/playback", tags=["playback"])

MAX_SERVERS = 4  # players kept running at once (each holds a loopback port and a thread or two)
IDLE_S = 120.0  # [s] a player no tab has had open for this long is shut down
REAP_PERIOD_S = 10.0  # [s] how often the idle players are looked for
PLAYBACK_DIR = "playback"  # under the data directory: traces kept in the database, written out

Key = tuple[int, int]  # (batch id, run index)


def clients_of(server: Any) -> int:
    """How many tabs viser counts on a player now (a tab counts once its camera is known)."""
    try:
        return len(server.server.get_clients())
    except Exception:  # noqa: BLE001 - a server that is stopping has none
        return 0


class Players:
    """The running PlaybackServers, keyed by (batch id, run index), least recently used first;
    the idle ones are stopped by :meth:`reap` (a daemon thread calls it every ``REAP_PERIOD_S``)."""

    def __init__(self, max_servers: int = MAX_SERVERS, idle_s: float = IDLE_S) -> None:
        self.max_servers = max_servers
        self.idle_s = idle_s
        self.servers: OrderedDict[Key, Any] = OrderedDict()
        self.last_used: dict[Key, float] = {}
        self.sockets: dict[Key, int] = {}  # WebSockets open through the proxy, per player
        self.lock = threading.Lock()
        self._reaper: threading.Thread | None = None

    def peek(self, key: Key) -> Any | None:
        """The running player of ``key``, if any (nothing is started)."""
        with self.lock:
            return self.servers.get(key)

    def touch(self, key: Key) -> None:
        """Count ``key`` as used now (its page was loaded)."""
        with self.lock:
            if key in self.servers:
                self.last_used[key] = time.monotonic()

    def socket_opened(self, key: Key) -> None:
        with self.lock:
            self.sockets[key] = self.sockets.get(key, 0) + 1
            self.last_used[key] = time.monotonic()

    def socket_closed(self, key: Key) -> None:
        with self.lock:
            left = self.sockets.get(key, 0) - 1
            if left > 0:
                self.sockets[key] = left
            else:
                self.sockets.pop(key, None)
            if key in self.servers:
                self.last_used[key] = time.monotonic()

    def in_use(self, key: Key) -> bool:
        """Whether a tab has the player of ``key`` open (a socket through us, or one viser counts)."""
        server = self.servers.get(key)
        return self.sockets.get(key, 0) > 0 or (server is not None and clients_of(server) > 0)

    def get(self, key: Key, start: Any) -> Any:
        """The player of ``key``, started by ``start()`` when none runs."""
        stopped = []
        with self.lock:
            server = self.servers.get(key)
            if server is None:
                while len(self.servers) >= self.max_servers:
                    old_key, old = self.servers.popitem(last=False)
                    self.last_used.pop(old_key, None)
                    stopped.append(old)
                server = start()
                self.servers[key] = server
            self.servers.move_to_end(key)
            self.last_used[key] = time.monotonic()
            self._start_reaper()
        for old in stopped:
            _stop(old)
        return server

    def reap(self, now: float | None = None) -> list[Key]:
        """Stop the players no tab has had open for ``idle_s``; answers their keys."""
        now = time.monotonic() if now is None else now
        idle: list[tuple[Key, Any]] = []
        with self.lock:
            for key in list(self.servers):
                if self.in_use(key):
                    self.last_used[key] = now
                elif now - self.last_used.get(key, now) >= self.idle_s:
                    idle.append((key, self.servers.pop(key)))
                    self.last_used.pop(key, None)
        for _, server in idle:
            _stop(server)
        return [key for key, _ in idle]

    def _start_reaper(self) -> None:  # the lock is held
        if self._reaper is None or not self._reaper.is_alive():
            self._reaper = threading.Thread(target=self._reap_forever, name="crossroads-playback-reaper",
                                            daemon=True)
            self._reaper.start()

    def _reap_forever(self) -> None:
        while True:
            time.sleep(REAP_PERIOD_S)
            try:
                self.reap()
            except Exception:  # noqa: BLE001 - one bad player must not end the reaping
                pass
            with self.lock:
                if not self.servers:
                    self._reaper = None
                    return

    def stop_all(self) -> None:
        with self.lock:
            servers = list(self.servers.values())
            self.servers.clear()
            self.last_used.clear()
        for server in servers:
            _stop(server)


def _stop(server: Any) -> None:
    try:
        server.stop()
    except Exception:  # noqa: BLE001 - a player that will not stop must not block the others
        pass


_PLAYERS = Players()
atexit.register(_PLAYERS.stop_all)


def view_path(batch_id: int, run_index: int) -> str:
    """Where the browser opens an episode's player (the page; its WebSocket is this without the
    final slash)."""
    return f"/api/playback/{batch_id}/{run_index}/view/"


def _trace_row(session: Any, batch_id: int, run_index: int) -> Any:
    """The trace row of an episode; 404 when there is no such episode or it kept no trace."""
    episode = crud.get_episode(session=session, batch_id=batch_id, run_index=run_index)
    if episode is None:
        raise HTTPException(status_code=404, detail=f"no episode {run_index} in batch {batch_id}")
    row = episode.trace
    if row is None:
        raise HTTPException(status_code=404, detail=f"no trace was kept for episode {run_index} "
                            f"of batch {batch_id} (see the batch's traces setting)")
    return row


def _trace_file(session: Any, batch_id: int, run_index: int, data_dir: Path) -> Path:
    row = _trace_row(session, batch_id, run_index)
    if row.path is not None:
        path = Path(row.path)
        if not path.is_file():
            raise HTTPException(status_code=404, detail="the episode's trace file is gone")
        return path
    path = data_dir / PLAYBACK_DIR / f"batch{batch_id}-run{run_index}.trace.npz"  # kept in the database
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_bytes(row.blob or b"")
        tmp.replace(path)
    return path


FORM_TYPE = "application/x-www-form-urlencoded"
OPENER = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Opening the 3D playback…</title></head>
<body style="font-family: sans-serif; margin: 3em">
<form method="post" action="/api/playback/{batch_id}/{run_index}">
<p>Opening the 3D playback of episode {run_index} of batch {batch_id}…</p>
<button type="submit">Open it</button></form>
<script>document.forms[0].submit()</script>
</body></html>
"""


def _opener(batch_id: int, run_index: int) -> HTMLResponse:
    return HTMLResponse(OPENER.format(batch_id=batch_id, run_index=run_index),
                        headers={"Cache-Control": "no-store"})


@router.post("/{batch_id}/{run_index}", responses={303: {"description": "a form submission: to the player"}})
def open_playback(batch_id: BatchId, run_index: RunIndex, request: Request, session: SessionDep,
                  settings: SettingsDep) -> Any:
    """Start (or reuse) the 3D playback of an episode; answers ``{batch_id, run_index, url}``, the
    url being the player's page on this server (a form submission, as from GET's page, is
    redirected to it instead)."""
    opened = _open(batch_id, run_index, session, settings)
    if request.headers.get("content-type", "").lower().startswith(FORM_TYPE):
        return RedirectResponse(opened["url"], status_code=303)
    return opened


def _open(batch_id: int, run_index: int, session: Any, settings: Any) -> dict[str, Any]:
    from crossroads.viz.playback import PlaybackServer

    trace = _trace_file(session, batch_id, run_index, settings.data_dir)

    def start() -> Any:
        return PlaybackServer([trace], host=LOOPBACK, port=0)

    _PLAYERS.get((batch_id, run_index), start)
    return {"batch_id": batch_id, "run_index": run_index, "url": view_path(batch_id, run_index)}


@router.get("/{batch_id}/{run_index}", response_class=HTMLResponse,
            responses={303: {"description": "the episode's player runs already: to it"}})
def playback_link(batch_id: BatchId, run_index: RunIndex, session: SessionDep) -> Response:
    """For a plain link: to the episode's player when one runs, otherwise a page that opens one
    (it POSTs to this path, then follows to the player). Starts nothing itself."""
    _trace_row(session, batch_id, run_index)  # 404s first
    if _PLAYERS.peek((batch_id, run_index)) is not None:
        return RedirectResponse(view_path(batch_id, run_index), status_code=303)
    return _opener(batch_id, run_index)


@router.get("/{batch_id}/{run_index}/view", include_in_schema=False)
def view_without_slash(batch_id: BatchId, run_index: RunIndex) -> RedirectResponse:
    return RedirectResponse(view_path(batch_id, run_index), status_code=307)


@router.get("/{batch_id}/{run_index}/view/", response_class=HTMLResponse)
def view_page(batch_id: BatchId, run_index: RunIndex, request: Request) -> Response:
    """The player's page (viser's viewer), from the player itself; while none runs (never
    opened, or shut down when idle) the page that opens one. Starts nothing itself."""
    server = _PLAYERS.peek((batch_id, run_index))
    if server is None:
        return _opener(batch_id, run_index)
    _PLAYERS.touch((batch_id, run_index))
    return fetch_page(int(server.server.get_port()), "/", request.headers.get("accept-encoding", ""))


@router.websocket("/{batch_id}/{run_index}/view")
@router.websocket("/{batch_id}/{run_index}/view/")
async def view_socket(websocket: WebSocket, batch_id: BatchId, run_index: RunIndex) -> None:
    """The player's WebSocket, joined to the player's own (refused when none runs)."""
    key = (batch_id, run_index)
    server = _PLAYERS.peek(key)
    if server is None:
        await websocket.close(code=1011, reason="no player runs for this episode: reload the page")
        return
    settings = websocket.app.state.settings
    await proxy_websocket(websocket, int(server.server.get_port()), allowed_hosts=tuple(settings.allowed_hosts),
                          on_open=lambda: _PLAYERS.socket_opened(key), on_close=lambda: _PLAYERS.socket_closed(key))
