"""Live runs: one episode of a scenario shown step by step in the 3D view while it runs.

:meth:`LiveRuns.start` starts a viser server on a loopback port (the browser reaches it through the
API's own port: :mod:`crossroads.api.viewer_proxy`) and the episode in a child process
(:mod:`crossroads.api.live_worker`: libsumo runs one simulation per process, and a crash there
must not take the API down), then returns at once. A pump thread per run receives the child's
frames and draws them with a :class:`~crossroads.viz.viewer.Viewer` on the server's scene, which
every tab opened on the viewer's URL shares. The child builds the world, then waits (at most
``viewer_wait_s``) for a first tab to connect, so the user sees the episode from its first step.

Limits: ``max_active`` runs at once (each is a SUMO process; :class:`LiveBusyError` beyond), and
``max_kept`` viewers kept open (finished runs are closed oldest first to make room).
"""

from __future__ import annotations

import itertools
import logging
import math
import multiprocessing as mp
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from crossroads.api import live_worker
from crossroads.api.viewer_proxy import LOOPBACK

log = logging.getLogger(__name__)

ACTIVE_STATUSES = ("starting", "waiting", "running")
LIVE_STATUSES = (*ACTIVE_STATUSES, "done", "failed", "stopped")
MAX_ACTIVE = 2  # episodes running at once (one SUMO process each)
MAX_KEPT = 4  # viewers kept open, finished ones included (one loopback port each)
VIEWER_WAIT_S = 10.0  # [s] a ready run waits this long for a first tab before it starts anyway
POLL_S = 0.2  # [s] how often the pump looks at a quiet child
INFO_PERIOD_S = 0.5  # [s] the viewer's status line changes at most this often
STOP_GRACE_S = 5.0  # [s] a stopped child gets this long to end before it is terminated


class LiveBusyError(RuntimeError):
    """As many live runs as allowed are running already."""


def _finite(data: Any) -> Any:
    """JSON-safe copy: non-finite floats (an empty scene's ``inf`` distance) become None."""
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: _finite(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return [_finite(v) for v in data]
    return data


@dataclass
class LiveRun:
    """One live episode: its viewer (a viser server), its child process and where it stands."""

    id: int
    scenario: str
    policy: str
    seed: int
    speed: float
    server: Any  # viser.ViserServer
    process: Any  # multiprocessing Process running live_worker.main
    conn: Any  # the receiving end of the child's pipe
    stop_event: Any  # multiprocessing Event: the child stops at its next step
    go: Any  # multiprocessing Event: the child starts the episode
    status: str = "starting"
    frames: int = 0
    result: dict[str, Any] | None = None
    error: str | None = None
    created_s: float = field(default_factory=time.monotonic)
    thread: threading.Thread | None = None
    viewer: Any = None
    info: Any = None  # the markdown status line in the viewer's GUI
    _info_at: float = 0.0

    @property
    def active(self) -> bool:
        return self.status in ACTIVE_STATUSES

    @property
    def port(self) -> int:
        return int(self.server.get_port())

    def public(self) -> dict[str, Any]:
        return {"id": self.id, "scenario": self.scenario, "policy": self.policy, "seed": self.seed,
                "speed": self.speed, "status": self.status, "frames": self.frames,
                "result": _finite(self.result), "error": self.error, "port": self.port}


class LiveRuns:
    """The live runs of this API process: start, read, stop, shutdown. Thread-safe.

    ``host``: where the viewers listen; loopback, as the API hands them on through its own port."""

    def __init__(self, *, host: str = LOOPBACK, max_active: int = MAX_ACTIVE,
                 max_kept: int = MAX_KEPT, viewer_wait_s: float = VIEWER_WAIT_S) -> None:
        self.host = host
        self.max_active = max_active
        self.max_kept = max(max_kept, max_active)
        self.viewer_wait_s = viewer_wait_s
        self._runs: dict[int, LiveRun] = {}
        self._ids = itertools.count(1)
        self._lock = threading.Lock()

    # --- starting --------------------------------------------------------------------------------

    def start(self, *, spec: dict[str, Any], base_dir: str, policy_ref: str, policy_name: str,
              seed: int, speed: float) -> LiveRun:
        """Open a viewer and start the episode in a child process; returns at once."""
        import viser

        with self._lock:
            active = sum(r.active for r in self._runs.values())
            if active >= self.max_active:
                raise LiveBusyError(f"{active} live runs are running already (at most "
                                    f"{self.max_active}); stop one or wait until one ends")
            evicted = self._evict()
            ctx = mp.get_context("spawn")  # never fork a process that runs threads
            conn, child_conn = ctx.Pipe(duplex=False)
            stop, go = ctx.Event(), ctx.Event()
            job = {"spec": spec, "base_dir": base_dir, "policy": policy_ref, "seed": seed,
                   "speed": speed}
            server = viser.ViserServer(host=self.host, port=0,
                                       label="Crossroads live", verbose=False)
            process = ctx.Process(target=live_worker.main, args=(child_conn, stop, go, job),
                                  name="crossroads-live", daemon=True)
            run = LiveRun(next(self._ids), str(spec.get("name", "")), policy_name, seed, speed,
                          server, process, conn, stop, go)
            run.info = server.gui.add_markdown(self._info_text(run))
            process.start()
            child_conn.close()  # the child holds the only sending end: its exit reads as EOF
            run.thread = threading.Thread(target=self._pump, args=(run,), daemon=True,
                                          name=f"crossroads-live-{run.id}")
            self._runs[run.id] = run
            run.thread.start()
        for old in evicted:
            self._close(old)
        return run

    def _evict(self) -> list[LiveRun]:
        """Finished runs to close so a new one fits under ``max_kept`` (the lock is held)."""
        finished = sorted((r for r in self._runs.values() if not r.active), key=lambda r: r.created_s)
        evicted = []
        while len(self._runs) >= self.max_kept and finished:
            old = finished.pop(0)
            del self._runs[old.id]
            evicted.append(old)
        return evicted

    # --- the pump: child → viewer ---------------------------------------------------------------

    def _pump(self, run: LiveRun) -> None:
        try:
            self._receive(run)
        except Exception as exc:  # noqa: BLE001 - a broken viewer ends the run, not the API
            log.exception("live run %s failed", run.id)
            self._end(run, "failed", error=f"{type(exc).__name__}: {exc}")
        finally:
            run.stop_event.set()
            run.process.join(STOP_GRACE_S)
            if run.process.is_alive():
                run.process.terminate()
                run.process.join(STOP_GRACE_S)
            run.conn.close()

    def _receive(self, run: LiveRun) -> None:
        while run.active:
            messages, closed = self._drain(run)
            self._dispatch(run, messages)
            if closed and run.active:  # ended without its last word: it died
                self._child_gone(run)

    @staticmethod
    def _drain(run: LiveRun) -> tuple[list[tuple[str, Any]], bool]:
        """What the child sent so far (waiting up to POLL_S for something), and whether its end
        of the pipe is closed. Everything before the close counts: the result comes last."""
        messages: list[tuple[str, Any]] = []
        try:
            if run.conn.poll(POLL_S):
                messages.append(run.conn.recv())
                while run.conn.poll(0):  # draw only the newest of the frames that piled up
                    messages.append(run.conn.recv())
        except (EOFError, OSError):
            return messages, True
        return messages, False

    def _dispatch(self, run: LiveRun, messages: list[tuple[str, Any]]) -> None:
        """Draw the newest frame of a run of frames; hand every other message on, in order."""
        frame = None
        for kind, payload in messages:
            if kind == "frame":
                frame = payload
                continue
            if frame is not None:
                self._show(run, frame)
                frame = None
            self._handle(run, kind, payload)
        if frame is not None:
            self._show(run, frame)

    def _handle(self, run: LiveRun, kind: str, payload: Any) -> None:
        if kind == "ready":
            self._ready(run, payload)
        elif kind == "result":
            self._end(run, "done", result=payload)
        elif kind == "stopped":
            self._end(run, "stopped")
        elif kind == "error":
            self._end(run, "failed", error=str(payload))

    def _ready(self, run: LiveRun, ready: dict[str, Any]) -> None:
        """The child's world is built: draw the intersection, wait for a tab, then go."""
        from crossroads.intersections.resolve import open_junction
        from crossroads.viz.viewer import Viewer
        from crossroads.viz.views import ViewControls

        junction = open_junction(ready["net"], ready["junction"])
        run.viewer = Viewer(run.server, junction, ready["candidates"])
        ViewControls(run.server.gui, run.viewer)  # camera (follow, top-down), layers, legend
        self._set(run, "waiting")
        deadline = time.monotonic() + self.viewer_wait_s
        while (not run.server.get_clients() and time.monotonic() < deadline
               and not run.stop_event.is_set()):
            time.sleep(POLL_S)
        if run.stop_event.is_set():
            return  # the child sees the stop while it waits and answers "stopped"
        run.go.set()
        self._set(run, "running")

    def _show(self, run: LiveRun, frame: dict[str, Any]) -> None:
        if run.viewer is None:
            return
        run.viewer.show_frame(frame)
        run.frames += 1
        now = time.monotonic()
        if now - run._info_at >= INFO_PERIOD_S:
            run._info_at = now
            self._update_info(run, frame)

    def _child_gone(self, run: LiveRun) -> None:
        run.process.join(STOP_GRACE_S)
        if run.stop_event.is_set():
            self._end(run, "stopped")
        else:
            self._end(run, "failed", error=f"the episode process ended without a result "
                                           f"(exit code {run.process.exitcode})")

    def _set(self, run: LiveRun, status: str) -> None:
        run.status = status
        self._update_info(run)

    def _end(self, run: LiveRun, status: str, *, result: dict[str, Any] | None = None,
             error: str | None = None) -> None:
        if not run.active:
            return
        run.result, run.error = result, error
        self._set(run, status)

    @staticmethod
    def _info_text(run: LiveRun, frame: dict[str, Any] | None = None) -> str:
        head = f"**Live: {run.scenario}** · policy {run.policy} · seed {run.seed}"
        if run.status == "done" and run.result:
            r = run.result
            travel = r.get("travel_time_s")
            tail = f"outcome **{r['outcome']}** after {r['time_s']:.1f} s" + (
                f" (travel time {travel:.1f} s)" if travel is not None else "")
        elif run.status == "failed":
            tail = f"**failed**: {run.error}"
        elif frame is not None:
            tail = f"running · t {float(frame.get('t', 0.0)):.1f} s"
        else:
            tail = {"starting": "building the world…", "waiting": "ready: starting…",
                    "running": "running", "stopped": "stopped"}.get(run.status, run.status)
        return f"{head}  \n{tail}"

    def _update_info(self, run: LiveRun, frame: dict[str, Any] | None = None) -> None:
        try:
            run.info.content = self._info_text(run, frame)
        except Exception:  # noqa: BLE001 - the server is closing; the status lives on in the API
            pass

    # --- reading and stopping --------------------------------------------------------------------

    def get(self, run_id: int) -> LiveRun | None:
        with self._lock:
            return self._runs.get(run_id)

    def list(self) -> list[LiveRun]:
        with self._lock:
            return sorted(self._runs.values(), key=lambda r: r.id)

    def stop(self, run_id: int) -> LiveRun | None:
        """Ask a run to stop at its next step (it ends ``stopped``); the viewer stays open."""
        run = self.get(run_id)
        if run is not None and run.active:
            run.stop_event.set()
        return run

    def _close(self, run: LiveRun) -> None:
        run.stop_event.set()
        if run.thread is not None:
            run.thread.join(STOP_GRACE_S * 2)
        try:
            run.server.stop()
        except Exception:  # noqa: BLE001 - a server that will not stop must not block the others
            log.exception("cannot stop the viewer of live run %s", run.id)

    def shutdown(self) -> None:
        """Stop every run and close every viewer."""
        with self._lock:
            runs = list(self._runs.values())
            self._runs.clear()
        for run in runs:
            run.stop_event.set()
        for run in runs:
            self._close(run)
