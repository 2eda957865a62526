"""The viser view: the Viewer's scene handles per frame, playback control, per-tab players.

Headless: a real ViserServer on a free port, no browser (a raw websocket plays the tab).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

viser = pytest.importorskip("viser")

from crossroads.evaluation.episode import run_episode  # noqa: E402
from crossroads.scenario.spec import load_scenario, to_world_config  # noqa: E402
from crossroads.evaluation.trace import Trace  # noqa: E402
from crossroads.idc.rule_based import RuleBasedController  # noqa: E402
from crossroads.sim.world import World  # noqa: E402
from crossroads.viz.playback import (  # noqa: E402
    MARKER_CLASS, Playback, PlaybackServer, fig7_series, junction_of, y_range)
from crossroads.viz.viewer import (  # noqa: E402
    ABNORMAL, COLLIDED, KIND_COLOURS, LiveRecorder, Viewer, collided_id, frame_of_observation, node_name)
from support import REPO_ROOT  # noqa: E402

SCENARIO = REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-left.yaml"


@pytest.fixture(scope="module")
def server() -> Iterator[viser.ViserServer]:
    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield srv
    srv.stop()


def _frame(i: int, participants: list[dict]) -> dict:
    return {"i": i, "t": i * 0.1, "signal": {"state": "GGgrrrGGgrrr", "light": "green", "remaining_s": 5.0},
            "speed_mode": "pass", "path_index": 0, "ego": [0.0, -20.0 + i, 0.0, 10.0, 1.57, 0, 0, 0],
            "participants": participants}


def _car(pid: str, x: float, abnormal: bool = False, kind: str = "vehicle") -> dict:
    return {"id": pid, "kind": kind, "x": x, "y": 5.0, "heading": 0.0, "speed": 8.0, "length": 4.5,
            "width": 1.8, "abnormal": abnormal, "perceived": True, "obs": None}


def test_viewer_follows_the_actors_of_a_real_trace(server: viser.ViserServer, trace: Trace) -> None:
    assert len(trace) > 20
    viewer = Viewer(server, junction_of(trace), trace.header["candidates"])
    try:
        assert viewer.static["road"] is not None and viewer.static["crosswalks"] is not None
        assert len(viewer.sensors) == 5 and viewer._lamps
        seen: dict[str, object] = {}
        for i in range(len(trace)):
            frame = trace.frame(i)
            viewer.show_frame(frame)
            ids = {p["id"] for p in frame["participants"]}
            assert viewer.actor_ids == ids
            for pid in ids:
                handle = viewer.actor_handle(pid)
                assert handle.name == f"/actors/{node_name(pid)}"
                assert not handle._impl.removed
                seen[pid] = handle
            for pid, handle in seen.items():  # those that left were taken off the scene
                assert handle._impl.removed == (pid not in ids)
        assert viewer.frames_shown == len(trace)
        assert viewer.trail.visible and len(viewer.trail.points) == len(trace) - 1
        assert set(viewer.lamp_colours().values()) <= {"green", "yellow", "red", "off"}
    finally:
        viewer.remove()


def test_viewer_marks_abnormal_actors_and_removes_leavers(server: viser.ViserServer, trace: Trace) -> None:
    viewer = Viewer(server, junction_of(trace), trace.header["candidates"])
    try:
        viewer.show_frame(_frame(0, [_car("car/1", 0.0), _car("bike#2", 3.0, kind="cyclist")]))
        assert viewer.actor_ids == {"car/1", "bike#2"}
        assert viewer.actor_handle("car/1").name == "/actors/car_1"
        assert tuple(viewer.actor_handle("bike#2").color) == KIND_COLOURS["cyclist"]
        assert viewer.mark_handle("car/1") is None
        viewer.show_frame(_frame(1, [_car("car/1", 1.0, abnormal=True), _car("ped", 9.0, kind="pedestrian")]))
        car = viewer.actor_handle("car/1")
        assert tuple(car.color) == ABNORMAL and viewer.mark_handle("car/1") is not None
        assert viewer.actor_ids == {"car/1", "ped"}
        assert np.allclose(car.position[:2], np.array([1.0, 5.0]) - viewer.origin[:2], atol=1e-4)
        mark = viewer.mark_handle("car/1")
        viewer.show_frame(_frame(2, [_car("car/1", 2.0, abnormal=False)]))
        assert viewer.mark_handle("car/1") is None and mark._impl.removed
        assert tuple(car.color) == KIND_COLOURS["vehicle"]
        viewer.show_frame(_frame(3, []))
        assert viewer.actor_ids == set() and car._impl.removed
        # chosen path highlighted; stepping back shortens the live trail
        if len(viewer._paths) > 1:
            viewer.show_frame(_frame(4, []) | {"path_index": 1})
            assert viewer._paths[1].thickness > viewer._paths[0].thickness
        viewer.show_frame(_frame(1, []))
        assert len(viewer._trail) == 2
    finally:
        viewer.remove()


def test_viewer_marks_the_participant_the_collision_names(server: viser.ViserServer, trace: Trace) -> None:
    """The outcome "hit vehicle veh58" marks veh58, not an abnormal participant beside it."""
    assert collided_id({"kind": "collision", "detail": "hit vehicle veh58"}) == "veh58"
    assert collided_id({"kind": "collision", "detail": "hit pedestrian ped.3#1"}) == "ped.3#1"
    assert collided_id({"kind": "timeout", "detail": "still driving after 6 s"}) is None
    viewer = Viewer(server, junction_of(trace), trace.header["candidates"])
    try:
        viewer.mark_collision("veh58")
        viewer.show_frame(_frame(0, [_car("veh58", 0.0), _car("veh64", 4.0, abnormal=True)]))
        assert tuple(viewer.actor_handle("veh58").color) == COLLIDED
        assert "veh58: hit by the ego" in viewer.mark_handle("veh58").text
        assert tuple(viewer.actor_handle("veh64").color) == ABNORMAL
        assert viewer.mark_handle("veh64").text == "⚠ veh64: abnormal"
        viewer.show_frame(_frame(1, [_car("veh58", 1.0, abnormal=True)]))  # both: one label says both
        assert viewer.mark_handle("veh58").text == "✖ veh58: hit by the ego (abnormal)"
        viewer.mark_collision(None)
        viewer.show_frame(_frame(2, [_car("veh58", 1.0)]))
        assert viewer.mark_handle("veh58") is None
        assert tuple(viewer.actor_handle("veh58").color) == KIND_COLOURS["vehicle"]
    finally:
        viewer.remove()


def test_frame_of_observation_matches_the_trace(trace: Trace) -> None:
    spec = load_scenario(SCENARIO)
    config = replace(to_world_config(spec), warmup_s=15.0, timeout_s=6.0)
    with World(config) as world:
        observation = world.reset(3)
        truth = world.truth
    frame = frame_of_observation(observation, truth, None, index=0)
    stored = trace.frame(0)
    assert [p["id"] for p in frame["participants"]] == [p["id"] for p in stored["participants"]]
    assert frame["signal"]["state"] == stored["signal"]["state"]


def test_live_run_shows_every_step(server: viser.ViserServer, trace: Trace) -> None:
    spec = load_scenario(SCENARIO)
    config = replace(to_world_config(spec), warmup_s=15.0, timeout_s=3.0)
    viewer = Viewer(server, junction_of(trace))
    try:
        live = LiveRecorder(viewer)
        with World(config) as world:
            result = run_episode(world, RuleBasedController(), seed=3, recorder=live)
        assert viewer.frames_shown == result.steps + 1 == len(live.trace())
        assert len(viewer._paths) == len(live.trace().header["candidates"])
        last = live.trace().frame(-1)
        assert viewer.actor_ids == {p["id"] for p in last["participants"]}
    finally:
        viewer.remove()


def test_playback_advances_scrubs_and_steps(server: viser.ViserServer, trace: Trace) -> None:
    player = Playback(server, trace)
    try:
        assert player.index == 0 and not player.playing and len(player.plots) == 4
        player.step(1)
        assert player.index == 1 and player.slider.value == 1
        player.step(-5)
        assert player.index == 0
        player.slider.value = 10  # what a scrub does (callbacks run on assignment)
        assert player.index == 10
        player.seek(0)
        player.set_speed(2.0)
        assert player.speed_dropdown.value == "2×"
        with pytest.raises(ValueError):
            player.set_speed(8.0)
        player.play()
        assert player.playing and player.play_button.label == "Pause"
        moved = player.advance(0.5)  # 0.5 s at 2× of 0.1 s frames: 10 frames
        assert moved == 10 and player.index == 10
        assert player.viewer.last_frame is not None and player.viewer.last_frame["i"] == 10
        player.advance(1e6)  # to the end: stops there
        assert player.index == len(trace) - 1 and not player.playing
        player.play()  # from the end: starts over
        assert player.index == 0
        time.sleep(0.5)  # the player's own thread moves it on
        assert player.index > 0
        player.pause()
        series = fig7_series(trace)
        assert set(series) == {"t", "speed", "steering", "acceleration", "speed_mode"}
        assert len(player.plots["speed"].data[1]) == len(trace)
    finally:
        player.close()


def test_playback_marks_the_hit_participant(server: viser.ViserServer, trace_file: Path, tmp_path: Path) -> None:
    hit = Trace.load(trace_file)
    victim = str(hit.frame(0)["participants"][0]["id"])
    hit.header["result"] = {**hit.header["result"], "kind": "collision", "detail": f"hit vehicle {victim}"}
    player = Playback(server, Trace.load(hit.save(tmp_path / "hit.trace.npz")))
    try:
        assert player.viewer.collided_id == victim
        assert f"hit **{victim}**" in player.info.content
        assert tuple(player.viewer.actor_handle(victim).color) == COLLIDED
    finally:
        player.close()


def test_y_range_is_finite_padded_and_ignores_nan() -> None:
    lo, hi = y_range(np.array([np.nan, 2.0, 4.0, np.nan]))
    assert lo < 2.0 and hi > 4.0 and np.isfinite([lo, hi]).all()
    assert y_range(np.array([5.0, 5.0])) == pytest.approx((4.5 - 0.08, 5.5 + 0.08))  # a flat line, centred
    lo, hi = y_range(np.array([np.nan, np.nan]))
    assert lo < 0.0 < hi


def test_playback_charts_keep_a_finite_scale_on_every_frame(server: viser.ViserServer, trace: Trace) -> None:
    """uPlot reads NaN as a value: a y scale auto-ranged over the NaN-padded "now" marker went NaN
    and the charts blank on every frame but the first. The marker stays out of the ranging and the
    y scales are fixed to the series' finite extent."""
    player = Playback(server, trace)
    try:
        series = fig7_series(trace)
        for frame in (0, 7, len(trace) - 1):
            player.seek(frame)
            for key, handle in player.plots.items():
                t, values, marker = handle.data
                assert np.array_equal(t, series["t"])
                assert np.array_equal(values, series[key], equal_nan=True)
                assert np.flatnonzero(~np.isnan(marker)).tolist() in ([frame], [])  # [] where the value is NaN
                assert handle.series[2]["auto"] is False and handle.series[2]["class"] == MARKER_CLASS
                lo, hi = handle.scales["y"]["range"]
                assert handle.scales["y"]["auto"] is False and np.isfinite([lo, hi]).all()
                finite = values[np.isfinite(values)]
                assert lo <= finite.min() and finite.max() <= hi
        lo, hi = player.plots["speed_mode"].scales["y"]["range"]
        assert lo < 0.0 and hi > 1.0  # both modes on the axis
    finally:
        player.close()


def _camera_message() -> bytes:
    import msgspec
    from viser._messages import ViewerCameraMessage

    message = ViewerCameraMessage(wxyz=(1.0, 0.0, 0.0, 0.0), position=(0.0, -50.0, 40.0), fov=1.0,
                                  near=0.01, far=1000.0, image_height=480, image_width=640,
                                  look_at=(0.0, 0.0, 0.0), up_direction=(0.0, 0.0, 1.0))
    return msgspec.msgpack.encode(message.as_serializable_dict())


def test_each_tab_gets_its_own_player(trace_file: Path, tmp_path: Path) -> None:
    from websockets.sync.client import connect

    other = Trace.load(trace_file)
    other.header["scenario"] = "second"
    second = other.save(tmp_path / "b.trace.npz")
    app = PlaybackServer([trace_file, second], host="127.0.0.1", port=0)
    try:
        assert app.url.startswith("http://127.0.0.1:")
        url = f"ws://127.0.0.1:{app.server.get_port()}"
        proto = f"viser-v{viser.__version__}"
        with connect(url, subprotocols=[proto]) as a, connect(url, subprotocols=[proto]) as b:
            for ws in (a, b):  # a tab counts as connected once it reports its camera
                ws.send(_camera_message())
            deadline = time.monotonic() + 20.0
            while len(app.players) < 2 and time.monotonic() < deadline:
                time.sleep(0.05)
            assert len(app.players) == 2
            pa, pb = app.players.values()
            assert pa is not pb and pa.viewer.target is not pb.viewer.target
            pa.seek(5)
            pb.seek(12)
            assert (pa.index, pb.index) == (5, 12)
            client = app.server.get_clients()[max(app.players)]
            app._open(client, 1)  # this tab picks the second episode; the other plays on
            assert app.players[client.client_id].trace.header["scenario"] == "second"
            assert pa.trace.header["scenario"] != "second"
    finally:
        app.stop()


def test_the_hud_says_when_the_shield_brakes(server: viser.ViserServer, trace: Trace) -> None:
    viewer = Viewer(server, junction_of(trace), trace.header["candidates"])
    try:
        viewer.show_frame({**_frame(0, []), "shield_braking": True})
        assert "shield brakes" in viewer.hud.text
        viewer.show_frame({**_frame(1, []), "shield_braking": False})
        assert "shield" not in viewer.hud.text
        viewer.show_frame(_frame(2, []))  # frames of traces and controllers without a shield
        assert "shield" not in viewer.hud.text
    finally:
        viewer.remove()
