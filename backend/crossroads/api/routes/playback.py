"""Playback: open a stored episode in the 3D view (a viser PlaybackServer on a free port).

``POST /playback/{batch_id}/{run_index}`` starts (or reuses) a player for the episode's trace and
answers its URL; ``GET`` on the same path redirects the browser there. At most
``MAX_SERVERS`` players run at once; the least recently used one is stopped to make room.
"""

from __future__ import annotations

import atexit
import socket
import threading
from collections import OrderedDict
from pathlib import Path
from typing import Any

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import RedirectResponse

from crossroads.api.deps import SessionDep, SettingsDep
from crossroads.store import crud

router = APIRouter(prefix="/playback", tags=["playback"])

MAX_SERVERS = 8  # viser servers kept running at once (each holds a port and a thread or two)
PLAYBACK_DIR = "playback"  # under the data directory: traces kept in the database, written out


class _Players:
    """The running PlaybackServers, keyed by (batch id, run index), least recently used first."""

    def __init__(self) -> None:
        self.servers: OrderedDict[tuple[int, int], Any] = OrderedDict()
        self.lock = threading.Lock()

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


def _trace_file(session: Any, batch_id: int, run_index: int, data_dir: Path) -> Path:
    episode = crud.get_episode(session=session, batch_id=batch_id, run_index=run_index)
    if episode is None:
        raise HTTPException(status_code=404, detail=f"no episode {run_index} in batch {batch_id}")
    row = episode.trace
    if row is None:
        raise HTTPException(status_code=404, detail=f"no trace was kept for episode {run_index} "
                            f"of batch {batch_id} (see the batch's traces setting)")
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


@router.post("/{batch_id}/{run_index}")
def open_playback(batch_id: int, run_index: int, request: Request, session: SessionDep,
                  settings: SettingsDep) -> dict[str, Any]:
    """Start (or reuse) the 3D playback of an episode; answers ``{url, port}``."""
    from crossroads.viz.playback import PlaybackServer

    trace = _trace_file(session, batch_id, run_index, settings.data_dir)
    bind = settings.host

    def start() -> Any:
        return PlaybackServer([trace], host=bind, port=_free_port(bind))

    server = _PLAYERS.get((batch_id, run_index), start)
    port = int(server.server.get_port())
    return {"batch_id": batch_id, "run_index": run_index, "port": port,
            "url": viewer_url(request, port)}


@router.get("/{batch_id}/{run_index}", response_class=RedirectResponse, status_code=303)
def playback_redirect(batch_id: int, run_index: int, request: Request, session: SessionDep,
                      settings: SettingsDep) -> RedirectResponse:
    """Like POST, then sends the browser to the player (a plain link works)."""
    opened = open_playback(batch_id, run_index, request, session, settings)
    return RedirectResponse(opened["url"], status_code=303)
