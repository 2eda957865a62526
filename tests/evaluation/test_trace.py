"""The episode trace: recording, the columnar file format, JSON frames, size."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from crossroads.evaluation.trace import KINDS, Trace, TraceRecorder

STATE_A = "GGgrrrGGgrrr"
STATE_B = "yyyrrryyyrrr"


def synthetic(steps: int = 600, participants: int = 100, seed: int = 0) -> TraceRecorder:
    """A recorder filled with smooth synthetic traffic: ``participants`` present at every step,
    each living ~200 steps, so people come and go throughout (like SUMO traffic)."""
    rng = np.random.default_rng(seed)
    rec = TraceRecorder()
    rec.header(scenario="synthetic", seed=seed, net="c_three_lane", junction="J0", task="left",
               candidates=[{"id": "left-0", "points": [[0.0, 0.0], [1.0, 1.0]]}], dt_s=0.1,
               policy="test")
    life = 200
    slots = [None] * participants  # (id, birth step, x0, y0, heading, speed, kind)
    next_id = 0
    for t in range(steps):
        for k in range(participants):
            if slots[k] is None or t - slots[k][1] >= life + (k % 37):
                kind = KINDS[next_id % 3]
                slots[k] = (f"{kind[:3]}{next_id}", t, rng.uniform(-100, 100), rng.uniform(-100, 100),
                            rng.uniform(-np.pi, np.pi), rng.uniform(1, 12), kind)
                next_id += 1
        ids = [s[0] for s in slots]
        age = np.array([(t - s[1]) * 0.1 for s in slots])
        heading = np.array([s[4] for s in slots])
        speed = np.array([s[5] for s in slots])
        x = np.array([s[2] for s in slots]) + age * speed * np.cos(heading)
        y = np.array([s[3] for s in slots]) + age * speed * np.sin(heading)
        kinds = [s[6] for s in slots]
        length = np.array([{"vehicle": 4.5, "cyclist": 1.6, "pedestrian": 0.25}[k] for k in kinds])
        width = np.array([{"vehicle": 1.8, "cyclist": 0.65, "pedestrian": 0.5}[k] for k in kinds])
        perceived = np.hypot(x, y) < 60.0
        truth = np.column_stack([x, y, speed, heading, length, width])
        observations = truth[perceived] + rng.normal(0, 0.15, (int(perceived.sum()), 6))
        rec.record(
            time_s=t * 0.1, signal_state=STATE_A if t < 400 else STATE_B,
            light="green" if t < 400 else "yellow", light_remaining_s=max(0.0, 40.0 - t * 0.1),
            speed_mode="pass", path_index=t % 3, ego=rng.normal(size=8), action=rng.normal(size=2),
            ids=ids, kinds=kinds, x=x, y=y, heading=heading, speed=speed, length=length, width=width,
            abnormal=np.arange(participants) % 10 == 0, perceived=perceived, observations=observations,
        )
    return rec


def small_recorder() -> TraceRecorder:
    """Three steps: bike0 leaves after step 0, ped0 arrives at step 1, step 2 is empty."""
    rec = TraceRecorder()
    rec.header(scenario="tiny", seed=7, net="/nets/x.net.xml", junction="J1", task="right")
    common = dict(signal_state=STATE_A, light="green", light_remaining_s=10.0, speed_mode="stop",
                  path_index=1, ego=np.arange(8.0))
    rec.record(time_s=0.0, action=[0.1, -0.2], ids=["veh0", "bike0"], kinds=["vehicle", "cyclist"],
               x=[1.0, 2.0], y=[3.0, 4.0], heading=[0.5, -0.5], speed=[5.0, 3.0], length=[4.5, 1.6],
               width=[1.8, 0.65], abnormal=[True, False], perceived=[False, True],
               observations=[[2.1, 4.1, 3.1, -0.4, 1.5, 0.6]], **common)
    rec.record(time_s=0.1, action=[0.0, 0.0], ids=["ped0", "veh0"], kinds=["pedestrian", "vehicle"],
               x=[9.0, 1.5], y=[9.5, 3.0], heading=[1.0, 0.5], speed=[1.2, 5.0], length=[0.25, 4.5],
               width=[0.5, 1.8], perceived=[True, True],
               observations=[[9.0, 9.4, 1.1, 1.0, 0.3, 0.5], [1.4, 3.1, 5.2, 0.5, 4.4, 1.9]], **common)
    rec.record(time_s=0.2, action=None, ids=[], kinds=[], x=[], y=[], heading=[], speed=[],
               length=[], width=[], **common)
    rec.finish(outcome="passed", time_s=0.2)
    return rec


def test_frame_contents() -> None:
    trace = small_recorder().trace()
    assert len(trace) == 3
    f0 = trace.frame(0)
    assert f0["t"] == 0.0 and f0["signal"] == {"state": STATE_A, "light": "green", "remaining_s": 10.0}
    assert f0["speed_mode"] == "stop" and f0["path_index"] == 1
    assert f0["ego"] == [float(v) for v in range(8)]
    assert f0["action"] == [0.1, -0.2]
    veh, bike = f0["participants"]
    assert veh == {"id": "veh0", "kind": "vehicle", "x": 1.0, "y": 3.0, "heading": 0.5, "speed": 5.0,
                   "length": 4.5, "width": 1.8, "abnormal": True, "perceived": False, "obs": None}
    assert bike["kind"] == "cyclist" and bike["perceived"] and not bike["abnormal"]
    assert bike["obs"] == [2.1, 4.1, 3.1, -0.4, 1.5, 0.6]
    # observations of frame 1 are found after frame 0's perceived row
    f1 = trace.frame(1)
    assert [p["id"] for p in f1["participants"]] == ["ped0", "veh0"]
    assert f1["participants"][0]["obs"] == [9.0, 9.4, 1.1, 1.0, 0.3, 0.5]
    assert f1["participants"][1]["obs"] == [1.4, 3.1, 5.2, 0.5, 4.4, 1.9]
    f2 = trace.frame(-1)
    assert f2["i"] == 2 and f2["participants"] == [] and f2["action"] == [None, None]
    assert trace.header["result"] == {"outcome": "passed", "time_s": 0.2}
    json.dumps(trace.to_json(), allow_nan=False)  # JSON-ready, no NaN
    with pytest.raises(IndexError):
        trace.frame(3)


def test_participants_appear_and_disappear() -> None:
    trace = small_recorder().trace()
    assert list(trace.ids) == ["veh0", "bike0", "ped0"]  # interned once, first-appearance order
    assert trace.steps_of("veh0").tolist() == [0, 1]
    assert trace.steps_of("bike0").tolist() == [0]
    assert trace.steps_of("ped0").tolist() == [1]
    assert trace.steps_of("nobody").tolist() == []
    big = synthetic(steps=300, participants=20).trace()
    present = [{p["id"] for p in big.frame(i)["participants"]} for i in range(len(big))]
    some = sorted(present[150])[0]
    steps = big.steps_of(some)
    assert 0 < steps[0] or steps[-1] < len(big) - 1  # it came or went mid-episode
    assert all((some in present[i]) == (i in set(steps.tolist())) for i in range(len(big)))


def test_round_trip(tmp_path: Path) -> None:
    rec = small_recorder()
    trace = rec.trace()
    path = trace.save(tmp_path / "ep.trace.npz")
    assert path.name == "ep.trace.npz"  # exactly the path given
    loaded = Trace.load(path)
    assert loaded == trace
    assert loaded.header == trace.header
    assert [loaded.frame(i) for i in range(3)] == [trace.frame(i) for i in range(3)]
    big = synthetic(steps=50, participants=30).trace()
    assert Trace.load(big.save(tmp_path / "big.npz")) == big


def test_recorded_values_are_float32_of_the_input() -> None:
    rec = TraceRecorder()
    rec.header(scenario="p", seed=0, net="n", task="left")
    x = np.array([123.456789012345])
    rec.record(time_s=0.1, signal_state="G", light="red", light_remaining_s=1.0, speed_mode="pass",
               path_index=0, ego=np.full(8, 1 / 3), action=[0, 0], ids=["a"], kinds=["vehicle"], x=x,
               y=[0], heading=[0], speed=[0], length=[4], width=[2])
    t = rec.trace()
    assert t.arrays["x"][0] == np.float32(x[0])
    assert abs(float(t.arrays["x"][0]) - x[0]) < 1e-5
    assert t.arrays["time_s"][0] == 0.1  # time stays float64


def test_size_of_a_600_step_100_participant_trace(tmp_path: Path) -> None:
    trace = synthetic(steps=600, participants=100).trace()
    assert len(trace) == 600 and trace.n_rows == 60_000
    path = trace.save(tmp_path / "big.trace.npz")
    size = path.stat().st_size
    print(f"\n600 steps x 100 participants: {size} bytes on disk, {trace.nbytes()} bytes in memory")
    assert size < 2_500_000  # vs ~15 MB as JSON
    assert Trace.load(path) == trace


def test_stride_keeps_the_last_frame() -> None:
    trace = synthetic(steps=25, participants=3).trace()
    frames = trace.to_json(stride=10)["frames"]
    assert [f["i"] for f in frames] == [0, 10, 20, 24]
    with pytest.raises(ValueError):
        trace.to_json(stride=0)


@pytest.mark.parametrize("bad, message", [
    ({"ego": np.zeros(7)}, "ego"),
    ({"action": [1.0]}, "action"),
    ({"kinds": ["truck"]}, "kind"),
    ({"light": "blue"}, "light"),
    ({"speed_mode": "fast"}, "speed_mode"),
    ({"x": [1.0, 2.0]}, "x has 2 values"),
    ({"perceived": [True], "observations": None}, "no observations"),
    ({"perceived": [True], "observations": np.zeros((2, 6))}, "observations"),
])
def test_record_rejects_inconsistent_steps(bad: dict, message: str) -> None:
    rec = TraceRecorder()
    rec.header(scenario="p", seed=0, net="n", task="left")
    step = dict(time_s=0.0, signal_state="G", light="green", light_remaining_s=1.0, speed_mode="pass",
                path_index=0, ego=np.zeros(8), action=np.zeros(2), ids=["a"], kinds=["vehicle"],
                x=[0.0], y=[0.0], heading=[0.0], speed=[0.0], length=[4.0], width=[2.0])
    step.update(bad)
    with pytest.raises(ValueError, match=message):
        rec.record(**step)


def test_adapters_for_world_objects() -> None:
    """start/record/finish with World-, Observation-, Decision- and Outcome-shaped objects."""
    snap = SimpleNamespace(ids=np.array(["v1", "p1"]), kind=np.array(["vehicle", "pedestrian"]),
                           x=np.array([1.0, 2.0]), y=np.array([0.0, 1.0]), heading=np.zeros(2),
                           speed=np.ones(2), length=np.array([4.5, 0.25]), width=np.array([1.8, 0.5]))
    truth = SimpleNamespace(participants=snap, abnormal_ids=frozenset({"v1"}))
    obs = SimpleNamespace(
        time_s=0.0, ego=np.zeros(8),
        light=SimpleNamespace(light="green", remaining_s=5.0, state="GrGr"),
        perceived=SimpleNamespace(rows=np.array([1]), kinds=np.array(["pedestrian"]),
                                  observations=np.array([[2.0, 1.0, 1.0, 0.0, 0.3, 0.5]])),
    )
    world = SimpleNamespace(config=SimpleNamespace(net_file=Path("/n/x.net.xml"), task="left"),
                            junction=SimpleNamespace(id="J0"), approach=SimpleNamespace(id="south_in"),
                            candidates=[SimpleNamespace(to_json=lambda: {"id": "left-0"})])
    rec = TraceRecorder()
    rec.start(world, 42)
    with pytest.raises(TypeError, match="truth"):  # the observation alone holds no true state
        rec.record(obs, SimpleNamespace(action=np.array([0.1, 0.2]), path_index=0, speed_mode="pass"))
    rec.record(obs, SimpleNamespace(action=np.array([0.1, 0.2]), path_index=0, speed_mode="pass"), truth)
    rec.finish(obs, SimpleNamespace(kind="collision", time_s=0.1, detail="hit v1", other_kind="vehicle"), truth)
    trace = rec.trace()
    assert trace.header["seed"] == 42 and trace.header["net"] == "/n/x.net.xml"
    assert trace.header["candidates"] == [{"id": "left-0"}] and trace.header["approach"] == "south_in"
    assert trace.header["result"]["kind"] == "collision"
    f0, f1 = trace.frame(0), trace.frame(1)
    assert [p["abnormal"] for p in f0["participants"]] == [True, False]
    assert [p["obs"] for p in f0["participants"]] == [None, [2.0, 1.0, 1.0, 0.0, 0.3, 0.5]]
    assert f1["speed_mode"] == "none" and f1["path_index"] == -1  # the final, undecided frame


def test_the_shield_is_recorded_and_older_traces_read_without_it(tmp_path: Path) -> None:
    rec = TraceRecorder()
    rec.header(scenario="tiny", seed=1, net="/nets/x.net.xml", junction="J1", task="left")
    for i, braking in enumerate((None, False, True)):
        rec.record(time_s=0.1 * i, signal_state=STATE_A, light="green", light_remaining_s=5.0, speed_mode="pass",
                   path_index=0, ego=np.zeros(8), action=[0.0, -4.5], shield_braking=braking)
    trace = rec.trace()
    assert [trace.frame(i)["shield_braking"] for i in range(3)] == [None, False, True]
    loaded = Trace.load(trace.save(tmp_path / "shield.npz"))
    assert loaded == trace
    old = tmp_path / "old.npz"  # as written before the shield was recorded
    arrays = {k: v for k, v in trace.arrays.items() if k != "shield"}
    header = np.frombuffer(json.dumps(trace.header).encode("utf-8"), dtype=np.uint8)
    np.savez_compressed(old, header=header, **arrays)
    assert [Trace.load(old).frame(i)["shield_braking"] for i in range(3)] == [None, None, None]
    assert small_recorder().trace().frame(0)["shield_braking"] is None  # no shield given
