"""Playback of stored episodes in the viser view, one independent player per browser tab.

:class:`Playback` plays one :class:`~crossroads.evaluation.trace.Trace` on a target (a
``viser.ClientHandle`` for one tab, or the whole ``viser.ViserServer``): a timeline slider (scrub),
play/pause, step ±1, speed 0.25×–4× (a dropdown, and slower/faster buttons the studio's keyboard
keys press), a jump-to-event list of the episode's events (the collision with its moment and the
participant hit, marked in the scene from that frame on), the view's camera, layers and legend
(:class:`~crossroads.viz.views.ViewControls`), and plots of speed, steering angle, acceleration and
speed mode over time (the paper's Fig. 7) as uPlot charts with the current frame marked.

:class:`PlaybackServer` starts a ViserServer and gives every tab that connects its own scene, GUI
and player (``on_client_connect``), with a dropdown to pick the episode when several traces are
served — so several tabs play different episodes at once.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from crossroads.evaluation.trace import SPEED_MODES, Trace
from crossroads.network.road import Junction
from crossroads.viz.viewer import Viewer, collided_id
from crossroads.viz.views import ViewControls

SPEEDS: dict[str, float] = {"0.25×": 0.25, "0.5×": 0.5, "1×": 1.0, "2×": 2.0, "4×": 4.0}
MAX_FPS = 30.0  # [1/s] frames shown at most this often (faster playback skips frames)
PLOT_MARKER_PERIOD_S = 0.25  # [s] the plots' "now" marker moves at most this often while playing
SPEED_STEPS = ("slower −", "faster +")  # the speed buttons (the studio's - and + keys press them)
NO_EVENT = "(pick an event to jump to)"


def event_text(event: Mapping[str, Any], collided: str | None = None) -> str:
    """One of an episode's events (``result["events"]``) in words."""
    kind, value = str(event.get("event", "?")), event.get("value")
    if kind == "speed_mode":
        return f"speed mode → {value}"
    if kind == "path":
        return f"path → #{value}"
    if kind == "shield_braking":
        return "shield brakes" if value else "shield releases"
    if kind == "blocked_by":
        return f"blocked by {value}"
    if kind == "outcome":
        return f"✖ collision with {collided}" if value == "collision" and collided else f"outcome: {value}"
    detail = value if value is not None else event.get("id", "")
    return f"{kind}: {detail}" if detail != "" else kind


def event_frames(times: np.ndarray, events: Sequence[Mapping[str, Any]]) -> list[int]:
    """The frame of each event: the first frame at or after its time (the last frame at most)."""
    t = np.asarray(times, dtype=np.float64)
    return [int(min(np.searchsorted(t, float(e.get("t", 0.0)) - 1e-6), len(t) - 1)) for e in events]

JunctionLoader = Callable[[Trace], Junction]


def junction_of(trace: Trace, net: str | Path | None = None) -> Junction:
    """The junction a trace was recorded on (``net`` overrides the header's network)."""
    from crossroads.intersections.resolve import open_junction

    return open_junction(str(net) if net is not None else trace.header["net"], trace.header.get("junction"))


def fig7_series(trace: Trace) -> dict[str, np.ndarray]:
    """The time series of the paper's Fig. 7: t [s], speed [m/s], steering δ [deg], acceleration
    [m/s²], speed mode (1 pass, 0 stop, NaN no decision)."""
    ego = trace.arrays["ego"].astype(np.float64)
    modes = np.array(SPEED_MODES)[trace.arrays["speed_mode"]]
    mode = np.where(modes == "pass", 1.0, np.where(modes == "stop", 0.0, np.nan))
    return {
        "t": trace.arrays["time_s"].astype(np.float64),
        "speed": np.hypot(ego[:, 2], ego[:, 3]),
        "steering": np.degrees(ego[:, 6]),
        "acceleration": ego[:, 7],
        "speed_mode": mode,
    }


def y_range(values: np.ndarray, pad: float = 0.08, min_span: float = 1.0) -> tuple[float, float]:
    """A fixed y range [lo, hi] for a chart of ``values``: their finite extent widened by ``pad``
    of the span on each side, and to at least ``min_span`` (a constant series is centred).

    Fixed, because uPlot takes NaN for a value rather than a gap: a scale auto-ranged over the
    NaN-padded "now" marker (or the speed mode's NaN "no decision") becomes NaN and the chart
    draws nothing."""
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return (-min_span / 2, min_span / 2)
    lo, hi = float(finite.min()), float(finite.max())
    span = hi - lo
    if span < min_span:
        mid = (lo + hi) / 2
        lo, hi, span = mid - min_span / 2, mid + min_span / 2, min_span
    return (lo - pad * span, hi + pad * span)


MARKER_CLASS = "crossroads-now"  # CSS class of the charts' "now" marker series

PLOTS: tuple[tuple[str, str, str], ...] = (
    ("speed", "speed [m/s]", "#1f77b4"),
    ("steering", "steering δ [deg]", "#2ca02c"),
    ("acceleration", "acceleration [m/s²]", "#d62728"),
    ("speed_mode", "speed mode (1 pass, 0 stop)", "#9467bd"),
)


class Playback:
    """One trace played on ``target`` (a ``viser.ClientHandle`` or ``viser.ViserServer``)."""

    def __init__(
        self,
        target: Any,
        trace: Trace,
        junction: Junction | None = None,
        *,
        title: str | None = None,
        autoplay: bool = False,
        plots: bool = True,
        folder: Any = None,
    ) -> None:
        self.target = target
        self.trace = trace
        self.n = len(trace)
        if self.n == 0:
            raise ValueError("the trace has no frames")
        self.dt = float(trace.header.get("dt_s", 0.1))
        self.index = 0
        self.playing = False
        self.speed = 1.0
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._ego_xy = trace.arrays["ego"][:, :2].astype(np.float64)
        self._series = fig7_series(trace)
        self._last_marker = -1.0
        self._syncing = False  # set while the player itself moves the slider
        self._spot_shown = False  # the collision's mark (hidden before its moment)
        self.viewer = Viewer(target, junction if junction is not None else junction_of(trace),
                             trace.header.get("candidates", ()))
        self.collided_id = collided_id(trace.header.get("result", {}))
        self.viewer.mark_collision(self.collided_id)  # the participant the outcome names
        self.events: list[dict[str, Any]] = [dict(e) for e in trace.header.get("result", {}).get("events", ())]
        self.event_frames = event_frames(self._series["t"], self.events)
        self.collision_frame = self._mark_collision_spot()
        self._build_gui(title, plots, folder)
        self.seek(0)
        self._thread = threading.Thread(target=self._run, name="crossroads-playback", daemon=True)
        self._thread.start()
        if autoplay:
            self.play()

    def _mark_collision_spot(self) -> int | None:
        """Mark where the ego hit (the participant's place on the last frame, else the ego's),
        shown from the collision's frame on; that frame (None: no collision)."""
        if self.trace.header.get("result", {}).get("kind") != "collision":
            return None
        last = self.n - 1
        frame = self.trace.frame(last)
        xy = [float(v) for v in frame["ego"][:2]]
        for p in frame.get("participants", ()):
            if str(p.get("id")) == self.collided_id:
                xy = [float(p["x"]), float(p["y"])]
        t = float(self._series["t"][last])
        who = f" with {self.collided_id}" if self.collided_id else ""
        self.viewer.show_collision_spot(xy, f"✖ collision{who} at t {t:.1f} s", visible=False)
        return last

    # --- GUI ----------------------------------------------------------------------------------------

    def _build_gui(self, title: str | None, plots: bool, folder: Any) -> None:
        gui = self.target.gui
        h = self.trace.header
        result = h.get("result", {})
        self._gui: list[Any] = []
        self._folder = folder if folder is not None else gui.add_folder("Playback")
        if folder is None:
            self._gui.append(self._folder)
        with self._folder:
            name = title or h.get("scenario") or "episode"
            outcome = f"**{result.get('kind', '?')}**"
            if self.collided_id is not None:
                outcome += f" (hit **{self.collided_id}**, drawn black and marked ✖)"
            self.info = gui.add_markdown(
                f"**{name}** · seed {h.get('seed')} · task {h.get('task')} · outcome {outcome}"
                f" · {self.n} frames")
            self.slider = gui.add_slider("Frame", min=0, max=max(self.n - 1, 1), step=1, initial_value=0)
            self.play_button = gui.add_button("Play")
            self.step_buttons = gui.add_button_group("Step", ["◀ −1", "+1 ▶"])
            self.speed_dropdown = gui.add_dropdown("Speed", tuple(SPEEDS), initial_value="1×")
            self.speed_buttons = gui.add_button_group("Speed ±", list(SPEED_STEPS))
            self.event_labels = [f"{k + 1}. t {float(e.get('t', 0.0)):.1f} s · {event_text(e, self.collided_id)}"
                                 for k, e in enumerate(self.events)]
            self.event_dropdown = gui.add_dropdown("Jump to event", (NO_EVENT, *self.event_labels),
                                                   initial_value=NO_EVENT)
            self.status = gui.add_markdown("")
            self.keys_hint = gui.add_markdown("Keys (in the studio): space play/pause · ←/→ step · +/− speed")
        self._gui += [self.info, self.slider, self.play_button, self.step_buttons, self.speed_dropdown,
                      self.speed_buttons, self.event_dropdown, self.status, self.keys_hint]
        self.view = ViewControls(gui, self.viewer)
        self._gui += self.view.handles

        @self.speed_buttons.on_click
        def _(_event: Any) -> None:
            self.change_speed(-1 if self.speed_buttons.value == SPEED_STEPS[0] else 1)

        @self.event_dropdown.on_update
        def _(_event: Any) -> None:
            label = str(self.event_dropdown.value)
            if label in self.event_labels:
                self.jump_to_event(self.event_labels.index(label))

        @self.slider.on_update
        def _(_event: Any) -> None:
            if not self._syncing:
                self.pause()
                self.seek(int(self.slider.value))

        @self.play_button.on_click
        def _(_event: Any) -> None:
            self.toggle()

        @self.step_buttons.on_click
        def _(_event: Any) -> None:
            self.pause()
            self.step(-1 if self.step_buttons.value.startswith("◀") else 1)

        @self.speed_dropdown.on_update
        def _(_event: Any) -> None:
            self.set_speed(SPEEDS[str(self.speed_dropdown.value)])

        self.plots: dict[str, Any] = {}
        if plots:
            from viser import uplot

            with gui.add_folder("Fig. 7: ego over time") as plot_folder:
                self._gui.append(plot_folder)
                # the "now" marker's legend entry would read NaN away from the current frame
                self._gui.append(gui.add_html(f"<style>.uplot tr.{MARKER_CLASS} {{display: none}}</style>"))
                t = self._series["t"]
                for key, label, colour in PLOTS:
                    self.plots[key] = gui.add_uplot(
                        data=(t, self._series[key], self._marker(key, 0)),
                        series=(uplot.Series(label="t [s]"),
                                uplot.Series(label=label, stroke=colour, width=2),
                                # NaN-padded, so kept out of the auto-ranging (a fixed y range too)
                                uplot.Series(label="now", stroke="#000000", width=0, auto=False,
                                             **{"class": MARKER_CLASS},
                                             points={"show": True, "size": 9, "fill": "#ff8800"})),
                        scales={"x": uplot.Scale(time=False, auto=True),
                                "y": uplot.Scale(auto=False, range=self._y_range(key))},
                        title=label, aspect=2.0,
                    )
                    self._gui.append(self.plots[key])

    def _y_range(self, key: str) -> tuple[float, float]:
        values = self._series[key]
        if key == "speed_mode":  # both modes on the axis, whichever the episode used
            values = np.concatenate([values, [0.0, 1.0]])
        return y_range(values)

    def _marker(self, key: str, i: int) -> np.ndarray:
        m = np.full(self.n, np.nan)
        m[i] = self._series[key][i]
        return m

    def _sync_gui(self, force_plots: bool) -> None:
        i = self.index
        self._syncing = True
        try:
            if int(self.slider.value) != i:
                self.slider.value = i
        finally:
            self._syncing = False
        s = self._series
        mode = SPEED_MODES[int(self.trace.arrays["speed_mode"][i])]
        light = self.viewer.last_frame.get("signal", {}) if self.viewer.last_frame else {}
        self.status.content = (
            f"t **{s['t'][i]:.1f} s** · frame {i}/{self.n - 1} · {s['speed'][i]:.2f} m/s · "
            f"δ {s['steering'][i]:.1f}° · a {s['acceleration'][i]:.2f} m/s² · mode **{mode}** · "
            f"light {light.get('light', '?')} · {'playing' if self.playing else 'paused'} "
            f"{self.speed:g}×")
        now = time.monotonic()
        if self.plots and (force_plots or now - self._last_marker >= PLOT_MARKER_PERIOD_S):
            for key, handle in self.plots.items():
                handle.data = (s["t"], s[key], self._marker(key, i))
            self._last_marker = now

    # --- control ------------------------------------------------------------------------------------

    def seek(self, i: int) -> None:
        """Show frame ``i`` (clamped to the trace)."""
        with self._lock:
            self.index = int(min(max(i, 0), self.n - 1))
            self.viewer.show_frame(self.trace.frame(self.index), trail=self._ego_xy[: self.index + 1])
            spot = self.viewer.collision_spot
            if spot is not None and self.collision_frame is not None:
                shown = self.index >= self.collision_frame
                if shown != self._spot_shown:
                    spot.visible = self._spot_shown = shown
            self._sync_gui(force_plots=not self.playing)

    def step(self, n: int = 1) -> None:
        self.seek(self.index + n)

    def jump_to_event(self, k: int) -> None:
        """Pause on the frame of the episode's event ``k`` (0-based)."""
        if not 0 <= k < len(self.events):
            raise ValueError(f"event must be within 0 and {len(self.events) - 1}, got {k}")
        self.pause()
        self.seek(self.event_frames[k])

    def change_speed(self, direction: int) -> None:
        """One step slower (-1) or faster (+1) along SPEEDS, kept within them."""
        values = sorted(SPEEDS.values())
        k = min(range(len(values)), key=lambda j: abs(values[j] - self.speed))
        self.set_speed(values[min(max(k + (1 if direction > 0 else -1), 0), len(values) - 1)])
        with self._lock:
            self._sync_gui(force_plots=False)

    def play(self) -> None:
        with self._lock:
            if self.index >= self.n - 1:
                self.seek(0)  # play again from the start
            self.playing = True
            self.play_button.label = "Pause"
            self._sync_gui(force_plots=False)

    def pause(self) -> None:
        with self._lock:
            if self.playing:
                self.playing = False
                self.play_button.label = "Play"
                self._sync_gui(force_plots=True)

    def toggle(self) -> None:
        self.pause() if self.playing else self.play()

    def set_speed(self, speed: float) -> None:
        if not 0.25 <= speed <= 4.0:
            raise ValueError(f"speed must be within 0.25 and 4, got {speed}")
        self.speed = float(speed)
        label = next((k for k, v in SPEEDS.items() if v == speed), None)
        if label is not None and self.speed_dropdown.value != label:
            self.speed_dropdown.value = label

    def advance(self, wall_s: float) -> int:
        """Move on by ``wall_s`` seconds of wall time at the current speed (when playing); returns
        the frames advanced. The background thread calls this; tests may call it directly."""
        with self._lock:
            if not self.playing:
                return 0
            self._carry = getattr(self, "_carry", 0.0) + wall_s * self.speed / self.dt
            frames = int(math.floor(self._carry))
            if frames <= 0:
                return 0
            self._carry -= frames
            target = min(self.index + frames, self.n - 1)
            moved = target - self.index
            self.seek(target)
            if self.index >= self.n - 1:
                self.pause()
            return moved

    def _run(self) -> None:
        last = time.monotonic()
        while not self._stop.is_set():
            period = max(self.dt / self.speed, 1.0 / MAX_FPS)
            self._stop.wait(period)
            now = time.monotonic()
            try:
                self.advance(now - last)
            except Exception:  # noqa: BLE001 — a tab that went away mid-frame ends its player
                if self._stop.is_set():
                    return
            last = now

    def close(self, remove: bool = True) -> None:
        """Stop the player; with ``remove``, take its GUI and scene off the target too."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        if remove:
            for handle in reversed(self._gui):
                try:
                    handle.remove()
                except Exception:  # noqa: BLE001 — already gone with its folder / client
                    pass
            self.viewer.remove()


class PlaybackServer:
    """A viser server where every browser tab gets its own player of one of ``traces``."""

    def __init__(
        self,
        traces: Sequence[str | Path],
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        net: str | Path | None = None,
        autoplay: bool = False,
        verbose: bool = False,
    ) -> None:
        import viser

        if not traces:
            raise ValueError("give at least one trace")
        self.paths = [Path(p) for p in traces]
        self.names = [self._label(p, k) for k, p in enumerate(self.paths)]
        self._cache: dict[int, Trace] = {}
        self._junctions: dict[str, Junction] = {}
        self.net = net
        self.autoplay = autoplay
        self.trace(0)  # fail now on an unreadable first trace, not in a tab
        self.players: dict[int, Playback] = {}
        self._lock = threading.Lock()
        self.server = viser.ViserServer(host=host, port=port, label="Crossroads", verbose=verbose)
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)

    @staticmethod
    def _label(path: Path, k: int) -> str:
        return f"{k}: {path.name}"

    @property
    def url(self) -> str:
        host = self.server.get_host()
        shown = "localhost" if host in ("0.0.0.0", "::", "") else host
        return f"http://{shown}:{self.server.get_port()}"

    def trace(self, k: int) -> Trace:
        if k not in self._cache:
            self._cache[k] = Trace.load(self.paths[k])
        return self._cache[k]

    def junction(self, trace: Trace) -> Junction:
        key = str(self.net) if self.net is not None else f"{trace.header['net']}#{trace.header.get('junction')}"
        if key not in self._junctions:
            self._junctions[key] = junction_of(trace, self.net)
        return self._junctions[key]

    def _connect(self, client: Any) -> None:
        chooser = None
        if len(self.paths) > 1:
            chooser = client.gui.add_dropdown("Episode", tuple(self.names), initial_value=self.names[0])

            @chooser.on_update
            def _(_event: Any) -> None:
                self._open(client, self.names.index(str(chooser.value)))

        self._open(client, 0)

    def _open(self, client: Any, k: int) -> None:
        with self._lock:
            old = self.players.pop(client.client_id, None)
        if old is not None:
            old.close()
        trace = self.trace(k)
        player = Playback(client, trace, self.junction(trace), title=self.paths[k].name,
                          autoplay=self.autoplay)
        with self._lock:
            self.players[client.client_id] = player

    def _disconnect(self, client: Any) -> None:
        with self._lock:
            player = self.players.pop(client.client_id, None)
        if player is not None:
            player.close(remove=False)

    def stop(self) -> None:
        with self._lock:
            players = list(self.players.values())
            self.players.clear()
        for player in players:
            player.close(remove=False)
        self.server.stop()
