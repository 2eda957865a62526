"""Playback: open a stored episode in the 3D view (a viser PlaybackServer on a free port).

``POST /playback/{batch_id}/{run_index}`` starts (or reuses) a player for the episode's trace and
answers its URL (JSON; a browser's form submission is sent there instead, 303). ``GET`` on the same
path starts nothing (a GET never changes anything): it redirects to the player when one runs
already, and otherwise answers a small page that submits that POST from the studio's own origin,
so a plain link opens the playback. At most ``MAX_SERVERS`` players run at once; the least
recently used one is stopped to make room.
"""

from __future__ import annotations

import atexit
import socket
import threading
from collections import OrderedDict
from pathlib import Path
from typing import Any

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from crossroads.api.deps import SessionDep, SettingsDep
from crossroads.api.params import BatchId, RunIndex
from crossroads.store import crud

router = APIRouter(prefix="/playback", tags=["playback"])

MAX_SERVERS = 8  # viser servers kept running at once (each holds a port and a thread or two)
PLAYBACK_DIR = "playback"  # under the data directory: traces kept in the database, written out


class _Players:
    """The running PlaybackServers, keyed by (batch id, run index), least recently used first."""

    def __init__(self) -> None:
        self.servers: OrderedDict[tuple[int, int], Any] = OrderedDict()
        self.lock = threading.Lock()

    def peek(self, key: tuple[int, int]) -> Any | None:
        """The running player of ``key``, if any (nothing is started)."""
        with self.lock:
            return self.servers.get(key)

    def get(self, key: tuple[int, int], start: Any) -> Any:
        with self.lock:
            server = self.servers.get(key)
            if server is not None:
                self.servers.move_to_end(key)
                return server
            while len(self.servers) >= MAX_SERVERS:
                _, old = self.servers.popitem(last=False)
                _stop(old)
            server = start()
            self.servers[key] = server
            return server

    def stop_all(self) -> None:
        with self.lock:
            servers = list(self.servers.values())
            self.servers.clear()
        for server in servers:
            _stop(server)


def _stop(server: Any) -> None:
    try:
        server.stop()
    except Exception:  # noqa: BLE001 - a player that will not stop must not block the others
        pass


_PLAYERS = _Players()
atexit.register(_PLAYERS.stop_all)


def _free_port(host: str) -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def viewer_url(request: Request, port: int) -> str:
    """The URL of a viser server of ours, by the host name the browser reached the API with."""
    host = request.url.hostname or "127.0.0.1"
    shown = f"[{host}]" if ":" in host else host
    return f"http://{shown}:{port}/"


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


@router.post("/{batch_id}/{run_index}", responses={303: {"description": "a form submission: to the player"}})
def open_playback(batch_id: BatchId, run_index: RunIndex, request: Request, session: SessionDep,
                  settings: SettingsDep) -> Any:
    """Start (or reuse) the 3D playback of an episode; answers ``{url, port}`` (a form
    submission, as from GET's page, is redirected to the player instead)."""
    opened = _open(batch_id, run_index, request, session, settings)
    if request.headers.get("content-type", "").lower().startswith(FORM_TYPE):
        return RedirectResponse(opened["url"], status_code=303)
    return opened


def _open(batch_id: int, run_index: int, request: Request, session: Any, settings: Any) -> dict[str, Any]:
    from crossroads.viz.playback import PlaybackServer

    trace = _trace_file(session, batch_id, run_index, settings.data_dir)
    bind = settings.host

    def start() -> Any:
        return PlaybackServer([trace], host=bind, port=_free_port(bind))

    server = _PLAYERS.get((batch_id, run_index), start)
    port = int(server.server.get_port())
    return {"batch_id": batch_id, "run_index": run_index, "port": port,
            "url": viewer_url(request, port)}


@router.get("/{batch_id}/{run_index}", response_class=HTMLResponse,
            responses={303: {"description": "the episode's player runs already: to it"}})
def playback_link(batch_id: BatchId, run_index: RunIndex, request: Request, session: SessionDep) -> Response:
    """For a plain link: to the episode's player when one runs, otherwise a page that opens one
    (it POSTs to this path, then follows to the player). Starts nothing itself."""
    _trace_row(session, batch_id, run_index)  # 404s first
    server = _PLAYERS.peek((batch_id, run_index))
    if server is not None:
        return RedirectResponse(viewer_url(request, int(server.server.get_port())), status_code=303)
    return HTMLResponse(OPENER.format(batch_id=batch_id, run_index=run_index),
                        headers={"Cache-Control": "no-store"})
