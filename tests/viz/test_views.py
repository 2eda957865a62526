"""The 3D view's ways of looking: camera modes (follow the ego, top-down), layer toggles, the
legend; the playback's jump-to-event list, the collision's spot and moment, the speed steps.
Headless: a real ViserServer (and for the cameras a raw websocket tab), no browser."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

viser = pytest.importorskip("viser")

from crossroads.evaluation.trace import Trace  # noqa: E402
from crossroads.viz.camera import CAMERA_MODES, FOLLOW_BACK_M, camera_pose  # noqa: E402
from crossroads.viz.playback import NO_EVENT, SPEED_STEPS, Playback, event_frames, event_text  # noqa: E402
from crossroads.viz.views import LAYERS, legend_html  # noqa: E402

from .test_viewer import _camera_message  # noqa: E402,TID252


@pytest.fixture(scope="module")
def server() -> Iterator[viser.ViserServer]:
    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield srv
    srv.stop()


def test_camera_poses() -> None:
    assert camera_pose("orbit", (5.0, 5.0), 0.3, 100.0) is None
    (px, py, pz), (lx, ly, lz) = camera_pose("follow", (10.0, -4.0), math.pi / 2, 100.0)  # heading north
    assert (px, py) == pytest.approx((10.0, -4.0 - FOLLOW_BACK_M)) and pz > 0, "behind the ego, above it"
    assert lx == pytest.approx(10.0) and ly > -4.0 and lz == 0.0, "looking ahead of it"
    (px, py, pz), look = camera_pose("top", (10.0, -4.0), 1.0, 100.0)
    assert look == (0.0, 0.0, 0.0) and pz > 100.0 and abs(py) < 0.02 * pz, "over the junction, nearly vertical"
    with pytest.raises(ValueError, match="camera mode"):
        camera_pose("sideways", (0.0, 0.0), 0.0, 10.0)
    assert set(CAMERA_MODES.values()) == {"orbit", "follow", "top"}


def test_event_words_and_frames() -> None:
    assert event_text({"event": "speed_mode", "value": "stop"}) == "speed mode → stop"
    assert event_text({"event": "path", "value": 1}) == "path → #1"
    assert event_text({"event": "shield_braking", "value": True}) == "shield brakes"
    assert event_text({"event": "outcome", "value": "collision"}, "veh7") == "✖ collision with veh7"
    assert event_text({"event": "outcome", "value": "passed"}) == "outcome: passed"
    assert event_text({"event": "gridlock_removed", "id": "veh3"}) == "gridlock_removed: veh3"
    times = np.array([0.0, 0.1, 0.2, 0.3])
    assert event_frames(times, [{"t": 0.0}, {"t": 0.2}, {"t": 0.25}, {"t": 9.0}]) == [0, 2, 3, 3]


def test_legend_names_every_colour() -> None:
    html = legend_html()
    for word in ("ego", "vehicle", "cyclist", "pedestrian", "abnormal", "hit by the ego", "chosen path",
                 "sensor ranges", "where the ego collided", "unseen"):
        assert word in html


def test_layers_hide_and_show_their_nodes(server: viser.ViserServer, trace: Trace) -> None:
    player = Playback(server, trace, plots=False)
    try:
        viewer = player.view.viewer
        assert set(player.view.layers) == set(LAYERS.values())
        player.seek(len(trace) // 2)
        viewer.set_layer("traffic", False)
        viewer.set_layer("paths", False)
        viewer.set_layer("sensors", False)
        viewer.set_layer("labels", False)
        assert not viewer.actors_root.visible and not viewer.paths_root.visible
        assert not any(h.visible for h in viewer.sensors.values()) and not viewer.hud.visible
        assert all(not m.visible for m in viewer._marks.values())
        viewer.set_layer("traffic", True)
        assert viewer.actors_root.visible and not viewer.paths_root.visible
        with pytest.raises(ValueError, match="layer"):
            viewer.set_layer("weather", False)
        # the checkbox in the tab does the same
        box = player.view.layers["paths"]
        box.value = False
        assert not viewer.paths_root.visible
        box.value = True
        assert viewer.paths_root.visible
    finally:
        player.close()


def test_jump_to_events_speed_steps_and_the_collision_moment(
        server: viser.ViserServer, trace_file: Path, tmp_path: Path) -> None:
    hit = Trace.load(trace_file)
    last = hit.frame(len(hit) - 1)
    victim = str(last["participants"][0]["id"])
    t_end = float(hit.arrays["time_s"][-1])
    events = [{"t": float(hit.arrays["time_s"][3]), "event": "speed_mode", "value": "stop"},
              {"t": round(t_end, 2), "event": "outcome", "value": "collision"}]
    hit.header["result"] = {**hit.header["result"], "kind": "collision", "detail": f"hit vehicle {victim}",
                            "events": events}
    player = Playback(server, Trace.load(hit.save(tmp_path / "hit.trace.npz")), plots=False)
    try:
        assert player.event_labels[0] == f"1. t {events[0]['t']:.1f} s · speed mode → stop"
        assert player.event_labels[1].endswith(f"✖ collision with {victim}")
        assert player.event_dropdown.value == NO_EVENT
        player.event_dropdown.value = player.event_labels[0]  # as a pick in the tab
        assert player.index == 3 and not player.playing
        spot = player.viewer.collision_spot
        assert spot is not None and not spot.visible, "not before the collision's moment"
        player.jump_to_event(1)
        assert player.index == len(hit) - 1 == player.collision_frame and spot.visible
        assert tuple(spot.position[:2]) == pytest.approx(
            tuple(player.viewer._xyz(np.array([float(last["participants"][0]["x"]),
                                               float(last["participants"][0]["y"])]))[:2]), abs=1e-3)
        player.seek(0)
        assert not spot.visible
        with pytest.raises(ValueError, match="event"):
            player.jump_to_event(2)

        assert player.speed == 1.0
        player.change_speed(+1)
        player.change_speed(+1)
        player.change_speed(+1)
        assert player.speed == 4.0 and player.speed_dropdown.value == "4×", "kept within the speeds"
        player.change_speed(-1)
        assert player.speed == 2.0
        assert list(SPEED_STEPS) == list(player.speed_buttons.options)
    finally:
        player.close()


def test_follow_and_top_down_move_the_tab_camera(trace_file: Path) -> None:
    """A real tab (a websocket that reports its camera, as a browser does): in follow mode the
    camera goes behind the ego on each frame; top-down puts it over the junction."""
    from websockets.sync.client import connect

    from crossroads.viz.playback import PlaybackServer

    app = PlaybackServer([trace_file], host="127.0.0.1", port=0)
    try:
        url = f"ws://127.0.0.1:{app.server.get_port()}"
        with connect(url, subprotocols=[f"viser-v{viser.__version__}"]) as tab:
            tab.send(_camera_message())
            deadline = time.monotonic() + 20.0
            while not app.players and time.monotonic() < deadline:
                time.sleep(0.05)
            (player,) = app.players.values()
            client = app.server.get_clients()[next(iter(app.players))]
            player.view.camera.value = "follow the ego"
            player.seek(10)
            x, y, heading = player.viewer._ego_pose
            expected, look = camera_pose("follow", (x, y), heading, player.viewer.scene_size_m)
            assert tuple(client.camera.position) == pytest.approx(expected, abs=1e-3)
            player.seek(20)
            moved = tuple(client.camera.position)
            assert moved != pytest.approx(expected, abs=1e-3) or player.viewer._ego_pose[:2] == (x, y)
            player.view.camera.value = "top-down"
            top, _ = camera_pose("top", (0.0, 0.0), 0.0, player.viewer.scene_size_m)
            assert tuple(client.camera.position) == pytest.approx(top, abs=1e-3)
            player.seek(25)  # top-down stays put while the ego moves
            assert tuple(client.camera.position) == pytest.approx(top, abs=1e-3)
    finally:
        app.stop()
