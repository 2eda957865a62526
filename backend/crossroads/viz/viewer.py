"""The 3D view of an intersection and an episode on a viser server (or on one browser tab).

A :class:`Viewer` draws on a *target*: a ``viser.ViserServer`` (every tab sees the same scene) or a
``viser.ClientHandle`` (the scene is that tab's own, so several tabs can play different episodes).
It builds the static scene once and keeps the handles; :meth:`Viewer.show_frame` then only changes
properties of those handles (positions, colours, visibility) inside ``target.atomic()``, and adds
or removes the boxes of participants that enter or leave.

Scene tree (names relative to the SUMO frame shifted so the junction's centre is the origin)::

    /junction/road, /junction/bike_lanes, /junction/sidewalks, /junction/medians,
    /junction/crosswalks, /junction/markings/{solid,dashed,centre}, /junction/stop_lines,
    /junction/signals/<approach>/<turn>/{pole,lamp}
    /paths/<k>                      candidate paths (the chosen one thick and orange)
    /ego, /ego/body, /ego/sensors/<name>, /ego/hud
    /ego_trail
    /actors/<id>, /actors/<id>/abnormal     participants (boxes coloured by kind) and their marks
    /collision, /collision/label    where the ego collided (shown by a playback from that moment)

Layers (:meth:`Viewer.set_layer`: sensors, paths, traffic, labels) hide or show whole subtrees;
the camera modes (:meth:`Viewer.set_camera_mode`: orbit, follow, top) place every tab's camera
on each frame (:mod:`crossroads.viz.camera`).

Frames are the JSON dicts of :meth:`crossroads.evaluation.trace.Trace.frame`;
:func:`frame_of_observation` makes the same dict from a live world's Observation, and
:class:`LiveRecorder` shows a running episode step by step (``run_episode(..., recorder=...)``).
"""

from __future__ import annotations

import math
import re
import threading
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from crossroads.constants import EGO_LENGTH_M, EGO_WIDTH_M
from crossroads.evaluation.trace import TraceRecorder
from crossroads.network.road import Junction
from crossroads.perception.sensors import DEFAULT_SENSORS, Sensor
from crossroads.viz.camera import camera_pose
from crossroads.viz.scene import SceneData, head_colour, junction_scene, sector_mesh

RGB = tuple[int, int, int]

ROAD: RGB = (70, 70, 74)
BIKE: RGB = (150, 95, 80)
SIDEWALK: RGB = (190, 190, 185)
MEDIAN: RGB = (85, 160, 70)
PAINT: RGB = (245, 245, 245)
YELLOW_PAINT: RGB = (240, 195, 0)
POLE: RGB = (60, 60, 60)

KIND_COLOURS: dict[str, RGB] = {
    "vehicle": (60, 120, 220),
    "cyclist": (240, 160, 30),
    "pedestrian": (170, 90, 210),
}
KIND_HEIGHTS_M: dict[str, float] = {"vehicle": 1.5, "cyclist": 1.7, "pedestrian": 1.8}
ABNORMAL: RGB = (230, 30, 30)
COLLIDED: RGB = (20, 20, 20)  # the participant the episode's collision names
EGO: RGB = (40, 200, 120)
EGO_HEIGHT_M = 1.5
UNPERCEIVED_OPACITY = 0.45  # participants no sensor covers are drawn translucent
TRAIL: RGB = (40, 200, 120)
PATH_OTHER: RGB = (120, 180, 255)
PATH_CHOSEN: RGB = (255, 130, 0)
LIGHT_COLOURS: dict[str, RGB] = {
    "green": (30, 220, 60), "yellow": (255, 200, 0), "red": (235, 30, 30), "off": (90, 90, 90),
}
SENSOR_COLOURS: dict[str, RGB] = {
    "lidar": (90, 170, 255), "camera": (255, 230, 90), "radar-front": (255, 120, 120),
    "radar-front-left": (255, 150, 120), "radar-front-right": (255, 150, 120),
}
SENSOR_OPACITY = 0.12
COLLISION_SPOT: RGB = (235, 30, 30)
LAYER_NAMES = ("sensors", "paths", "traffic", "labels")
Z_PATH = 0.08
Z_TRAIL = 0.1


def yaw_wxyz(heading_rad: float) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of a rotation by ``heading_rad`` about +z."""
    return (math.cos(heading_rad / 2.0), 0.0, 0.0, math.sin(heading_rad / 2.0))


def node_name(participant_id: str) -> str:
    """A participant id as one scene-tree name component (no '/', no spaces)."""
    return re.sub(r"[^A-Za-z0-9_.:#-]", "_", str(participant_id)) or "_"


def _polyline_segments(points: np.ndarray, z: float) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64)[:, :2]
    p3 = np.column_stack([pts, np.full(len(pts), z)])
    return np.stack([p3[:-1], p3[1:]], axis=1).astype(np.float32)


class Viewer:
    """The intersection and one episode's frames on a viser server or client.

    ``target``: a ``viser.ViserServer`` or ``viser.ClientHandle`` (anything with ``scene``,
    ``atomic()`` and optionally ``initial_camera``/``camera``). ``candidates``: the candidate
    paths as JSON dicts (``header["candidates"]`` of a trace, or ``CandidatePath.to_json()``).
    """

    def __init__(
        self,
        target: Any,
        junction: Junction,
        candidates: Sequence[Mapping[str, Any]] = (),
        *,
        sensors: Sequence[Sensor] = DEFAULT_SENSORS,
        scene: SceneData | None = None,
    ) -> None:
        self.target = target
        self.junction = junction
        self.data = scene if scene is not None else junction_scene(junction)
        self.origin = np.array([*self.data.center, 0.0], dtype=np.float64)
        self._lock = threading.RLock()
        self._actors: dict[str, Any] = {}  # participant id -> box handle
        self._actor_state: dict[str, tuple[Any, ...]] = {}  # id -> (kind, abnormal, perceived, dims)
        self._marks: dict[str, Any] = {}  # participant id -> label handle (abnormal or hit ones)
        self._mark_text: dict[str, str] = {}  # participant id -> its label's text
        self.collided_id: str | None = None  # the participant the outcome says the ego hit
        self._paths: list[Any] = []
        self._path_index: int | None = None
        self._signal_state: str | None = None
        self._lamps: dict[str, tuple[Any, tuple[int, ...]]] = {}
        self._trail: list[tuple[int, float, float]] = []
        self.frames_shown = 0
        self.last_frame: dict[str, Any] | None = None
        self.layers: dict[str, bool] = dict.fromkeys(LAYER_NAMES, True)
        self.camera_mode = "orbit"
        self._ego_pose: tuple[float, float, float] | None = None  # scene x, y, heading
        self.collision_spot: Any = None
        with self.target.atomic():
            self._build_static(sensors)
            self.set_candidates(candidates)
        self._set_camera()

    # --- static scene -----------------------------------------------------------------------------

    def _xyz(self, points: np.ndarray) -> np.ndarray:
        """Network-frame points (..., 3) or (..., 2) → scene frame (junction centre at the origin)."""
        pts = np.asarray(points, dtype=np.float64)
        if pts.shape[-1] == 2:
            pts = np.concatenate([pts, np.zeros((*pts.shape[:-1], 1))], axis=-1)
        return (pts - self.origin).astype(np.float32)

    def _mesh(self, name: str, mesh: Any, color: RGB, **kw: Any) -> Any:
        if mesh.empty:
            return None
        return self.target.scene.add_mesh_simple(
            name, self._xyz(mesh.vertices), mesh.faces, color=color, side="double",
            cast_shadow=False, **kw)

    def _lines(self, name: str, segments: np.ndarray, color: RGB, thickness: float) -> Any:
        if len(segments) == 0:
            return None
        return self.target.scene.add_line_segments(
            name, self._xyz(segments), colors=color, thickness=thickness)

    def _build_static(self, sensors: Sequence[Sensor]) -> None:
        scene = self.target.scene
        d = self.data
        scene.set_up_direction("+z")
        self.static: dict[str, Any] = {
            "road": self._mesh("/junction/road", d.road, ROAD, receive_shadow=True),
            "bike_lanes": self._mesh("/junction/bike_lanes", d.bike_lanes, BIKE),
            "sidewalks": self._mesh("/junction/sidewalks", d.sidewalks, SIDEWALK),
            "medians": self._mesh("/junction/medians", d.medians, MEDIAN),
            "crosswalks": self._mesh("/junction/crosswalks", d.crosswalks, PAINT),
            "solid": self._lines("/junction/markings/solid", d.solid_lines, PAINT, 0.15),
            "dashed": self._lines("/junction/markings/dashed", d.dashed_lines, PAINT, 0.12),
            "centre": self._lines("/junction/markings/centre", d.centre_lines, YELLOW_PAINT, 0.15),
            "stop_lines": self._lines("/junction/stop_lines", d.stop_lines, PAINT, 0.4),
        }
        # parents of the candidate paths and the participants: one switch hides a whole layer
        self.paths_root = scene.add_frame("/paths", show_axes=False)
        self.actors_root = scene.add_frame("/actors", show_axes=False)
        for head in d.signal_heads:
            base = f"/junction/signals/{node_name(head.approach)}/{head.turn}"
            pos = self._xyz(head.position)
            scene.add_box(f"{base}/pole", color=POLE, dimensions=(0.12, 0.12, float(head.position[2])),
                          position=(float(pos[0]), float(pos[1]), float(head.position[2]) / 2.0))
            lamp = scene.add_icosphere(f"{base}/lamp", radius=0.3, color=LIGHT_COLOURS["off"],
                                       subdivisions=2, position=tuple(float(v) for v in pos))
            self._lamps[head.id] = (lamp, head.link_indices)
        # the ego: a frame moved each step, its body and its sensors' sectors hang under it
        self.ego = scene.add_frame("/ego", show_axes=False, visible=False)
        self.ego_body = scene.add_box("/ego/body", color=EGO,
                                      dimensions=(EGO_LENGTH_M, EGO_WIDTH_M, EGO_HEIGHT_M),
                                      position=(0.0, 0.0, EGO_HEIGHT_M / 2.0))
        self.sensors: dict[str, Any] = {}
        for sensor in sensors:
            m = sector_mesh(sensor)
            self.sensors[sensor.name] = scene.add_mesh_simple(
                f"/ego/sensors/{node_name(sensor.name)}", m.vertices, m.faces,
                color=SENSOR_COLOURS.get(sensor.name, (200, 200, 255)), opacity=SENSOR_OPACITY,
                side="double", cast_shadow=False, receive_shadow=False)
        self.hud = scene.add_label("/ego/hud", "", position=(0.0, 0.0, EGO_HEIGHT_M + 1.5),
                                   anchor="bottom-center")
        self.trail = scene.add_line_segments(
            "/ego_trail", np.zeros((1, 2, 3), np.float32), colors=TRAIL, thickness=0.25,
            visible=False)

    @property
    def scene_size_m(self) -> float:
        return float(max(self.data.bounds[2] - self.data.bounds[0], self.data.bounds[3] - self.data.bounds[1]))

    def _set_camera(self) -> None:
        r = self.scene_size_m
        position, look_at = (0.0, -0.55 * r, 0.45 * r), (0.0, 0.0, 0.0)
        camera = getattr(self.target, "initial_camera", None) or getattr(self.target, "camera", None)
        if camera is None:
            return
        try:
            camera.position = position
            camera.look_at = look_at
        except Exception:  # noqa: BLE001 — a camera that cannot be set yet is not an error
            pass

    # --- layers and cameras ---------------------------------------------------------------------------

    def set_layer(self, layer: str, visible: bool) -> None:
        """Show or hide a layer: ``sensors`` (their ranges), ``paths`` (the candidate paths),
        ``traffic`` (every other road user), ``labels`` (the HUD and the marks over road users)."""
        if layer not in self.layers:
            raise ValueError(f"layer must be one of {', '.join(LAYER_NAMES)}, got {layer!r}")
        with self._lock, self.target.atomic():
            self.layers[layer] = bool(visible)
            if layer == "sensors":
                for handle in self.sensors.values():
                    handle.visible = visible
            elif layer == "paths":
                self.paths_root.visible = visible
            elif layer == "traffic":
                self.actors_root.visible = visible
            else:
                self.hud.visible = visible
                for mark in self._marks.values():
                    mark.visible = visible

    def set_camera_mode(self, mode: str) -> None:
        """``orbit`` (the user's camera), ``follow`` (behind the ego, moved every frame) or
        ``top`` (looking down on the junction)."""
        camera_pose(mode, (0.0, 0.0), 0.0, self.scene_size_m)  # checks the mode
        with self._lock:
            self.camera_mode = mode
            self._place_cameras()

    def _cameras(self) -> list[Any]:
        """The camera of each tab this viewer draws for (a client's own, or every client's)."""
        if hasattr(self.target, "get_clients"):
            return [c.camera for c in self.target.get_clients().values()]
        camera = getattr(self.target, "camera", None)
        return [] if camera is None else [camera]

    def _place_cameras(self) -> None:
        x, y, heading = self._ego_pose or (0.0, 0.0, 0.0)
        pose = camera_pose(self.camera_mode, (x, y), heading, self.scene_size_m)
        if pose is None:
            return
        position, look_at = pose
        for camera in self._cameras():
            try:
                camera.position = position
                camera.look_at = look_at
                camera.up_direction = (0.0, 0.0, 1.0)
            except Exception:  # noqa: BLE001 - a tab whose camera is not known yet (or gone)
                pass

    def show_collision_spot(self, xy: Sequence[float] | None, text: str = "", visible: bool = True) -> None:
        """Mark where the ego collided (network frame ``xy``, a red translucent sphere with a
        label), or remove the mark (None)."""
        with self._lock, self.target.atomic():
            if self.collision_spot is not None:
                self.collision_spot.remove()
                self.collision_spot = None
            if xy is None:
                return
            pos = self._xyz(np.array([float(xy[0]), float(xy[1])]))
            self.collision_spot = self.target.scene.add_icosphere(
                "/collision", radius=2.2, color=COLLISION_SPOT, opacity=0.35, subdivisions=2,
                position=(float(pos[0]), float(pos[1]), 1.0), visible=visible)
            self.target.scene.add_label("/collision/label", text, position=(0.0, 0.0, 2.6),
                                        anchor="bottom-center")

    # --- candidates ---------------------------------------------------------------------------------

    def set_candidates(self, candidates: Sequence[Mapping[str, Any]]) -> None:
        """Replace the candidate paths (JSON dicts with ``points`` rows ``[x, y, ...]``)."""
        with self._lock, self.target.atomic():
            for handle in self._paths:
                handle.remove()
            self._paths = []
            self._path_index = None
            for k, cand in enumerate(candidates):
                pts = np.asarray([row[:2] for row in cand["points"]], dtype=np.float64)
                if len(pts) < 2:
                    continue
                self._paths.append(self.target.scene.add_line_segments(
                    f"/paths/{k}", self._xyz(_polyline_segments(pts, Z_PATH)), colors=PATH_OTHER,
                    thickness=0.2))

    def _highlight_path(self, index: int) -> None:
        if index == self._path_index:
            return
        for k, handle in enumerate(self._paths):
            chosen = k == index
            colour = np.asarray(PATH_CHOSEN if chosen else PATH_OTHER, dtype=np.uint8)
            handle.colors = np.ascontiguousarray(np.broadcast_to(colour, handle.points.shape))
            handle.thickness = 0.5 if chosen else 0.2
        self._path_index = index

    # --- per frame ----------------------------------------------------------------------------------

    @property
    def actor_ids(self) -> set[str]:
        """Ids of the participants currently drawn."""
        return set(self._actors)

    def actor_handle(self, participant_id: str) -> Any:
        return self._actors[participant_id]

    def mark_collision(self, participant_id: str | None) -> None:
        """Mark ``participant_id`` as the one the ego hit (drawn dark, labelled), on the frames
        shown from now on; None: no collision."""
        with self._lock:
            self.collided_id = participant_id

    def mark_handle(self, participant_id: str) -> Any | None:
        return self._marks.get(participant_id)

    def lamp_colours(self) -> dict[str, str]:
        """Each signal head's current colour name (``"<approach>/<turn>" -> "green" | ...``)."""
        state = self._signal_state or ""
        return {hid: head_colour(state, links) for hid, (_, links) in self._lamps.items()}

    def show_frame(self, frame: Mapping[str, Any], trail: np.ndarray | None = None) -> None:
        """Show one frame (a :meth:`Trace.frame` dict). ``trail``: the ego's past positions (N, 2)
        in the network frame; None keeps a trail of the frames shown so far (live runs)."""
        with self._lock, self.target.atomic():
            self._show_ego(frame, trail)
            self._show_signals(str(frame.get("signal", {}).get("state", "")))
            self._highlight_path(int(frame.get("path_index", -1)))
            self._show_participants(frame.get("participants", ()))
        self.frames_shown += 1
        self.last_frame = dict(frame)

    def _show_ego(self, frame: Mapping[str, Any], trail: np.ndarray | None) -> None:
        ego = frame["ego"]
        x, y, vx, vy, phi = (float(v) for v in ego[:5])
        pos = self._xyz(np.array([x, y]))
        self.ego.position = (float(pos[0]), float(pos[1]), 0.0)
        self.ego.wxyz = yaw_wxyz(phi)
        self.ego.visible = True
        self._ego_pose = (float(pos[0]), float(pos[1]), phi)
        if self.camera_mode != "orbit":
            self._place_cameras()
        signal = frame.get("signal", {})
        self.hud.text = (f"t {float(frame.get('t', 0.0)):.1f} s · {math.hypot(vx, vy):.1f} m/s · "
                         f"{frame.get('speed_mode', 'none')} · {signal.get('light', '?')}"
                         + (" · shield brakes" if frame.get("shield_braking") else ""))
        if trail is None:
            i = int(frame.get("i", len(self._trail)))
            while self._trail and self._trail[-1][0] >= i:  # stepped back: forget the future
                self._trail.pop()
            self._trail.append((i, x, y))
            trail = np.array([(px, py) for _, px, py in self._trail])
        trail = np.asarray(trail, dtype=np.float64).reshape(-1, 2)
        if len(trail) >= 2:
            self.trail.points = self._xyz(_polyline_segments(trail, Z_TRAIL))
            self.trail.visible = True
        else:
            self.trail.visible = False

    def _show_signals(self, state: str) -> None:
        if state == self._signal_state:
            return
        for lamp, links in self._lamps.values():
            lamp.color = LIGHT_COLOURS[head_colour(state, links)]
        self._signal_state = state

    def _show_participants(self, participants: Sequence[Mapping[str, Any]]) -> None:
        scene = self.target.scene
        seen: set[str] = set()
        for p in participants:
            pid = str(p["id"])
            seen.add(pid)
            kind = str(p.get("kind", "vehicle"))
            height = KIND_HEIGHTS_M.get(kind, 1.5)
            dims = (max(float(p["length"]), 0.3), max(float(p["width"]), 0.3), height)
            abnormal, perceived = bool(p.get("abnormal", False)), bool(p.get("perceived", True))
            pos = self._xyz(np.array([float(p["x"]), float(p["y"])]))
            position = (float(pos[0]), float(pos[1]), height / 2.0)
            wxyz = yaw_wxyz(float(p["heading"]))
            hit = pid == self.collided_id
            colour = COLLIDED if hit else ABNORMAL if abnormal else KIND_COLOURS.get(kind, (200, 200, 200))
            opacity = None if perceived else UNPERCEIVED_OPACITY
            state = (kind, abnormal, perceived, dims, hit)
            handle = self._actors.get(pid)
            if handle is None:
                handle = scene.add_box(f"/actors/{node_name(pid)}", color=colour, dimensions=dims,
                                       opacity=opacity, position=position, wxyz=wxyz)
                self._actors[pid] = handle
            else:
                handle.position = position
                handle.wxyz = wxyz
                if self._actor_state.get(pid) != state:
                    handle.color = colour
                    handle.dimensions = dims
                    handle.opacity = opacity
            self._actor_state[pid] = state
            self._mark(pid, mark_text(pid, abnormal, hit), height)
        for pid in [q for q in self._actors if q not in seen]:
            self._marks.pop(pid, None)  # removed with its parent
            self._mark_text.pop(pid, None)
            self._actors.pop(pid).remove()
            self._actor_state.pop(pid, None)

    def _mark(self, pid: str, text: str | None, height: float) -> None:
        """The label over a participant: added, changed or removed to say ``text``."""
        mark = self._marks.get(pid)
        if text is None:
            if mark is not None:
                mark.remove()
                del self._marks[pid]
                self._mark_text.pop(pid, None)
        elif mark is None:
            self._marks[pid] = self.target.scene.add_label(
                f"/actors/{node_name(pid)}/abnormal", text, position=(0.0, 0.0, height),
                anchor="bottom-center", visible=self.layers["labels"])
            self._mark_text[pid] = text
        elif self._mark_text.get(pid) != text:
            mark.text = text
            self._mark_text[pid] = text

    def clear(self) -> None:
        """Remove every participant and the trail (the static scene stays)."""
        with self._lock, self.target.atomic():
            for pid in list(self._actors):
                self._actors.pop(pid).remove()
            self._marks.clear()
            self._mark_text.clear()
            self._actor_state.clear()
            self._trail.clear()
            self.trail.visible = False
            self.ego.visible = False

    def remove(self) -> None:
        """Remove everything this viewer drew."""
        with self._lock, self.target.atomic():
            self.clear()
            for handle in self._paths:
                handle.remove()
            self._paths = []
            self.show_collision_spot(None)
            for name in ("/junction", "/ego", "/ego_trail", "/paths", "/actors"):
                try:
                    self.target.scene.remove_by_name(name)
                except Exception:  # noqa: BLE001 — already gone
                    pass


def mark_text(pid: str, abnormal: bool, hit: bool) -> str | None:
    """The label over a participant: the one the ego hit, an abnormal one, or none."""
    if hit:
        return f"✖ {pid}: hit by the ego" + (" (abnormal)" if abnormal else "")
    return f"⚠ {pid}: abnormal" if abnormal else None


COLLISION_DETAIL = re.compile(r"^hit \S+ (?P<id>\S+)$")


def collided_id(result: Mapping[str, Any]) -> str | None:
    """The participant a trace's result says the ego hit (its ``detail``: "hit <kind> <id>")."""
    if result.get("kind") != "collision":
        return None
    found = COLLISION_DETAIL.match(str(result.get("detail", "")))
    return found["id"] if found else None


def frame_of_observation(observation: Any, truth: Any, decision: Any = None,
                         index: int | None = None) -> dict[str, Any]:
    """A live world's Observation and GroundTruth (and the controller's Decision) as a
    :meth:`Trace.frame` dict."""
    snap = truth.participants
    rows = {int(r) for r in np.asarray(observation.perceived.rows).reshape(-1)}
    abnormal = truth.abnormal_ids
    participants = [
        {"id": str(snap.ids[j]), "kind": str(snap.kind[j]), "x": float(snap.x[j]),
         "y": float(snap.y[j]), "heading": float(snap.heading[j]), "speed": float(snap.speed[j]),
         "length": float(snap.length[j]), "width": float(snap.width[j]),
         "abnormal": str(snap.ids[j]) in abnormal, "perceived": j in rows}
        for j in range(len(snap.ids))
    ]
    light = observation.light
    frame: dict[str, Any] = {
        "t": float(observation.time_s),
        "signal": {"state": light.state, "light": light.light, "remaining_s": float(light.remaining_s)},
        "speed_mode": "none" if decision is None else str(decision.speed_mode),
        "path_index": -1 if decision is None else int(decision.path_index),
        "shield_braking": None if decision is None else getattr(decision, "shield_braking", None),
        "ego": [float(v) for v in np.asarray(observation.ego).reshape(-1)],
        "participants": participants,
    }
    if index is not None:
        frame["i"] = int(index)
    return frame


class LiveRecorder(TraceRecorder):
    """A :class:`TraceRecorder` that also shows every step on a :class:`Viewer` as it happens.

    Pass it as ``recorder`` to :func:`crossroads.evaluation.episode.run_episode` for a live view;
    the trace is recorded as usual. ``realtime``: 1.0 paces the run at the world's Δt per step
    (0: as fast as it runs)."""

    def __init__(self, viewer: Viewer, realtime: float = 0.0) -> None:
        super().__init__()
        self.viewer = viewer
        self.realtime = float(realtime)
        self._last = 0.0

    def start(self, world: Any, seed: int, scenario: str | None = None) -> None:
        super().start(world, seed, scenario)
        self.viewer.clear()
        self.viewer.mark_collision(None)
        self.viewer.set_candidates(self._header.get("candidates", ()))

    def _show(self, observation: Any, truth: Any, decision: Any) -> None:
        self.viewer.show_frame(frame_of_observation(observation, truth, decision, index=len(self) - 1))
        if self.realtime > 0.0:
            wait = self._header.get("dt_s", 0.1) / self.realtime - (time.monotonic() - self._last)
            if wait > 0:
                time.sleep(wait)
            self._last = time.monotonic()

    def record(self, observation: Any = None, decision: Any = None, truth: Any = None, /, **step: Any) -> None:
        super().record(observation, decision, truth, **step)
        if observation is not None:
            self._show(observation, truth, decision)

    def finish(self, observation: Any = None, outcome: Any = None, truth: Any = None, /, **result: Any) -> None:
        super().finish(observation, outcome, truth, **result)
        if outcome is not None:
            self.viewer.mark_collision(collided_id({"kind": getattr(outcome, "kind", None),
                                                    "detail": getattr(outcome, "detail", "")}))
        if observation is not None:
            self._show(observation, truth, None)
