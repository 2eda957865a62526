"""The 108-vector state (SPEC §4): layout, selection, padding, tracking error, network input."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch

from crossroads.arrays import NumpyOps, TorchTrigNumpyOps
from crossroads.constants import PREVIEW_DISTANCES_M, STATE_DIM
from crossroads.geometry import wrap_angle
from crossroads.idc import state as S
from crossroads.planning import plan_candidates
from planning.factories import four_way_junction


@pytest.fixture(scope="module")
def candidates():
    return plan_candidates(four_way_junction(n_lanes=3, median_m=3.0), "left")


def test_layout() -> None:
    assert (S.EGO.start, S.EGO.stop, S.TRACK.start, S.TRACK.stop, S.OTHERS.start, S.OTHERS.stop) == (0, 8, 8, 12, 12, 108)
    assert STATE_DIM == 108 and S.N_OTHERS == 16
    assert (S.VEHICLES, S.CYCLISTS, S.PEDESTRIANS) == (slice(12, 60), slice(60, 84), slice(84, 108))
    assert S.KIND_ROWS == {"vehicle": slice(0, 8), "cyclist": slice(8, 12), "pedestrian": slice(12, 16)}
    assert S.KIND_OF_SLOT.count("vehicle") == 8 and S.KIND_OF_SLOT[-1] == "pedestrian"
    st = np.arange(108.0)
    block = S.others_block(st)
    assert block.shape == (16, 6) and block[0, 0] == 12 and block[15, 5] == 107
    assert S.others_block(np.zeros((3, 5, 108))).shape == (3, 5, 16, 6)


def test_pad_participant() -> None:
    ego = np.array([10.0, 20.0, 5.0, 0.0, math.pi / 2, 0.0, 0.0, 0.0])
    pad = S.pad_participant(ego)
    assert pad[0] == pytest.approx(10.0) and pad[1] == pytest.approx(20.0 - S.PAD_DISTANCE_M)
    assert pad[2] == 0.0 and pad[3] == pytest.approx(math.pi / 2)
    assert pad[4] > 0 and pad[5] > 0


def test_select_others_sorts_truncates_and_pads() -> None:
    rng = np.random.default_rng(0)
    n = 30
    obs = np.column_stack([rng.uniform(-50, 50, (n, 2)), rng.uniform(0, 10, n), rng.uniform(-3, 3, n),
                           np.full(n, 4.0), np.full(n, 2.0)])
    kinds = np.array(["vehicle"] * 12 + ["cyclist"] * 2 + ["pedestrian"] * 15 + ["tram"])
    ego = np.array([1.0, 2.0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0])
    out = S.select_others(ego, obs, kinds)
    assert out.shape == (16, 6)
    d = np.hypot(out[:, 0] - 1.0, out[:, 1] - 2.0)
    veh = obs[:12]
    expected = veh[np.argsort(np.hypot(veh[:, 0] - 1, veh[:, 1] - 2))[:8]]
    np.testing.assert_array_equal(out[:8], expected)
    assert np.all(np.diff(d[:8]) >= 0) and np.all(np.diff(d[12:]) >= 0)
    np.testing.assert_array_equal(out[8:10], obs[12:14][np.argsort(np.hypot(obs[12:14, 0] - 1, obs[12:14, 1] - 2))])
    np.testing.assert_allclose(out[10], S.pad_participant(ego))
    np.testing.assert_allclose(out[11], S.pad_participant(ego))
    empty = S.select_others([1.0, 2.0], np.zeros((0, 6)), np.array([]))
    np.testing.assert_allclose(empty, np.tile(S.pad_participant([1.0, 2.0, 0, 0, 0, 0, 0, 0]), (16, 1)))
    np.testing.assert_allclose(S.select_others([1.0, 2.0], obs, kinds, ego_heading=0.3), out)


def test_tracking_error_frame_and_wrap() -> None:
    ego = np.array([1.0, 3.0, 6.0, 0.0, math.pi - 0.1, 0.0, 0.0, 0.0])
    # reference at the origin heading +y: the ego is 3 m ahead and 1 m to the right
    err = S.tracking_error(ego, 0.0, 0.0, math.pi / 2, 5.0)
    np.testing.assert_allclose(err, [3.0, -1.0, 1.0, math.pi / 2 - 0.1], atol=1e-12)
    err = S.tracking_error(ego, 0.0, 0.0, -math.pi + 0.1, 5.0)  # across ±π
    assert err[3] == pytest.approx(-0.2)
    # rigid motions of the scene leave it unchanged; Δx² + Δy² is the squared distance
    for th in (0.4, -2.5):
        c, s = math.cos(th), math.sin(th)
        e2 = ego.copy()
        e2[0], e2[1], e2[4] = c * ego[0] - s * ego[1] + 7, s * ego[0] + c * ego[1] - 2, ego[4] + th
        e = S.tracking_error(e2, 7.0, -2.0, -math.pi + 0.1 + th, 5.0)
        np.testing.assert_allclose(e, S.tracking_error(ego, 0.0, 0.0, -math.pi + 0.1, 5.0), atol=1e-12)
    batch = np.tile(ego, (4, 2, 1))
    assert S.tracking_error(batch, np.zeros((4, 2)), 0.0, 0.0, 0.0).shape == (4, 2, 4)


def test_reference_point_matches_the_paths_projection(candidates) -> None:
    rng = np.random.default_rng(2)
    for c in candidates:
        for k in rng.integers(1, len(c.points) - 1, size=20):
            x, y = c.points[k] + rng.uniform(-0.8, 0.8, 2)
            ref = S.reference_point(c.points, c.heading, c.v_pass, x, y)
            proj = c.project(x, y)
            assert ref.index == proj.index
            rx, ry, rh, rv = c.reference_at(proj.s_m, "pass")
            assert (ref.x, ref.y) == pytest.approx((rx, ry), abs=1e-9)
            assert ref.heading == pytest.approx(rh, abs=1e-9)
            assert ref.v == pytest.approx(np.interp(proj.s_m, c.s, c.v_pass), abs=1e-9)
            err = S.tracking_error(np.array([x, y, 0, 0, 0, 0, 0, 0]), ref.x, ref.y, ref.heading, ref.v)
            assert math.hypot(err[0], err[1]) == pytest.approx(abs(proj.lateral_m), abs=1e-9)
            assert err[1] == pytest.approx(proj.lateral_m, rel=1e-3, abs=1e-9)  # frame: interpolated heading
            hinted = S.reference_point(c.points, c.heading, c.v_pass, x, y, hint=int(k) - 3)
            assert hinted == ref
            far = S.reference_point(c.points, c.heading, c.v_pass, x, y, hint=len(c.points) - 2)
            assert far == ref  # the window's edge falls back to the whole path


def test_build_states(candidates) -> None:
    c0 = candidates[0]
    k = 120
    x, y = c0.points[k] + [0.3, -0.2]
    ego = np.array([x, y, 4.0, 0.1, c0.heading[k] + 0.05, 0.02, 0.01, 0.3])
    obs = np.array([[x + 10, y, 5.0, 0.0, 4.5, 1.8], [x, y + 5, 1.0, 1.0, 0.5, 0.5]])
    others = S.select_others(ego, obs, np.array(["vehicle", "pedestrian"]))
    states = S.build_states(ego, others, candidates, "pass")
    assert states.shape == (len(candidates), 108)
    for j, c in enumerate(candidates):
        np.testing.assert_array_equal(states[j, S.EGO], ego)
        np.testing.assert_array_equal(S.others_block(states[j]), others)
        ref = S.reference_point(c.points, c.heading, c.v_pass, x, y)
        np.testing.assert_allclose(states[j, S.TRACK], S.tracking_error(ego, ref.x, ref.y, ref.heading, ref.v), atol=1e-12)
    stop = S.build_states(ego, others, candidates, "stop")
    np.testing.assert_array_equal(np.delete(stop, S.DV, axis=1), np.delete(states, S.DV, axis=1))
    for j, c in enumerate(candidates):
        ref = S.reference_point(c.points, c.heading, c.v_stop, x, y)
        assert stop[j, S.DV] == pytest.approx(ego[2] - ref.v)
    with pytest.raises(ValueError):
        S.build_states(ego, others, candidates, "crawl")


def test_reference_points_torch_equals_numpy(candidates) -> None:
    rng = np.random.default_rng(5)
    paths = S.path_tensors(candidates, dtype=torch.float64)
    assert paths.points.shape[0] == len(candidates)
    b = 64
    pidx = rng.integers(0, len(candidates), b)
    xy = np.array([candidates[p].points[rng.integers(0, len(candidates[p].points))] for p in pidx])
    xy += rng.uniform(-1, 1, xy.shape)
    xy[0] = candidates[pidx[0]].points[-1] + [3.0, 3.0]  # beyond the end (padding of shorter paths)
    stop = rng.random(b) < 0.5
    ref = S.reference_points_torch(paths, torch.tensor(xy), torch.tensor(pidx), torch.tensor(stop))
    for i in range(b):
        c = candidates[pidx[i]]
        r = S.reference_point(c.points, c.heading, c.v_stop if stop[i] else c.v_pass, *xy[i])
        got = (ref.x[i].item(), ref.y[i].item(), ref.heading[i].item(), ref.v[i].item())
        assert got == pytest.approx((r.x, r.y, r.heading, r.v), abs=1e-9)
    # one path for all, and gradients through tracking_error with the reference as data
    ego = torch.zeros(b, 8, dtype=torch.float64)
    ego[:, :2] = torch.tensor(xy)
    ego.requires_grad_(True)
    one = S.reference_points_torch(S.path_tensors(candidates[:1], dtype=torch.float64), ego[:, :2])
    err = S.tracking_error(ego, one.x, one.y, one.heading, one.v)
    (err**2).sum().backward()
    assert torch.isfinite(ego.grad).all() and ego.grad[:, :2].abs().sum() > 0


def rigid(states: np.ndarray, th: float, tx: float, ty: float) -> np.ndarray:
    """The same scene rotated by th and shifted (x_track is path-relative, so unchanged)."""
    out = states.copy()
    c, s = math.cos(th), math.sin(th)
    out[..., 0], out[..., 1] = c * states[..., 0] - s * states[..., 1] + tx, s * states[..., 0] + c * states[..., 1] + ty
    out[..., 4] = states[..., 4] + th
    o, oo = S.others_block(states), S.others_block(out)
    oo[..., 0], oo[..., 1] = c * o[..., 0] - s * o[..., 1] + tx, s * o[..., 0] + c * o[..., 1] + ty
    oo[..., 3] = wrap_angle(o[..., 3] + th)
    return out


def random_states(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    st = rng.uniform(-1, 1, size=(n, 108))
    st[:, :2] *= 100
    st[:, 4] *= math.pi
    o = S.others_block(st)
    o[..., :2] = st[:, None, :2] + rng.uniform(-60, 60, (n, 16, 2))
    o[..., 3] *= math.pi
    o[..., 4:] = np.abs(o[..., 4:]) * 4 + 0.3
    return st


def test_network_input_is_pose_invariant_and_backend_free() -> None:
    st = random_states(32)
    x = S.network_input(st)
    assert x.shape == (32, 108)
    np.testing.assert_allclose(S.network_input(rigid(st, 1.3, -40.0, 250.0)), x, atol=1e-9)
    assert np.all(x[:, [0, 1, 4]] == 0.0)
    xt = S.network_input(torch.tensor(st))
    np.testing.assert_allclose(xt.numpy(), x, rtol=1e-9, atol=1e-9)
    # pads: 100 m behind, speed 0, facing away
    ego = np.array([3.0, 4.0, 5.0, 0.0, 0.7, 0.0, 0.0, 0.0])
    states = np.concatenate([ego, np.zeros(4), S.select_others(ego, np.zeros((0, 6)), np.array([])).ravel()])
    pads = S.others_block(S.network_input(states))
    np.testing.assert_allclose(pads[:, :4], np.tile([-S.PAD_DISTANCE_M / S.POSITION_SCALE_M, 0, 0, 0], (16, 1)), atol=1e-9)
    t = torch.tensor(st, requires_grad=True)
    S.network_input(t).sum().backward()
    assert torch.isfinite(t.grad).all()


def _select_others_per_kind(ego, obs, kinds):
    """select_others as first written: a stable sort within each kind."""
    out = np.tile(S.pad_participant(ego), (S.N_OTHERS, 1))
    d2 = (obs[:, 0] - ego[0]) ** 2 + (obs[:, 1] - ego[1]) ** 2
    for kind in S.KINDS:
        idx = np.flatnonzero(kinds == kind)
        chosen = idx[np.argsort(d2[idx], kind="stable")][: S.SLOTS[kind]]
        out[S.KIND_ROWS[kind].start: S.KIND_ROWS[kind].start + len(chosen)] = obs[chosen]
    return out


def test_select_others_is_a_stable_sort_within_each_kind() -> None:
    rng = np.random.default_rng(7)
    for n in (0, 1, 5, 40, 120):
        ego = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), 3.0, 0.0, rng.uniform(-3, 3), 0, 0, 0])
        obs = rng.uniform(-60, 60, (n, 6))
        obs[: n // 3, :2] = np.round(obs[: n // 3, :2])  # equal distances: ties keep the input order
        obs[n // 3: n // 2, :2] = obs[: n // 2 - n // 3, :2]
        kinds = rng.choice(["vehicle", "cyclist", "pedestrian", "tram"], n)
        got = S.select_others(ego, obs, kinds)
        assert got.tobytes() == _select_others_per_kind(ego, obs, kinds).tobytes()


def test_build_states_is_the_array_formula(candidates) -> None:
    """build_states computes x_track of the few candidates on floats: the same numbers as the array
    formulation on references()."""
    rng = np.random.default_rng(8)
    others = S.select_others(np.zeros(8), rng.uniform(-30, 30, (20, 6)), np.array(["vehicle"] * 20))
    pts = np.concatenate([c.points for c in candidates])
    for mode in ("pass", "stop"):
        for k in rng.integers(0, len(pts), 60):
            x, y = pts[k] + rng.normal(0, 2.0, 2)
            e = np.array([x, y, rng.uniform(0, 12), 0.1, rng.uniform(-4, 4), 0.02, 0.01, 0.3])
            ref = S.references(candidates, float(x), float(y), mode)
            dx, dy = x - ref.x, y - ref.y
            c, s = np.cos(ref.heading), np.sin(ref.heading)
            track = np.column_stack([c * dx + s * dy, c * dy - s * dx, e[S.VX] - ref.v,
                                     np.mod(e[S.PHI] - ref.heading + math.pi, 2.0 * math.pi) - math.pi])
            expected = np.concatenate([np.broadcast_to(e, (len(candidates), 8)), track,
                                       np.broadcast_to(others.reshape(1, -1), (len(candidates), 96))], axis=1)
            for cands in (list(candidates), tuple(candidates)):  # a tuple is remembered by identity
                assert S.build_states(e, others, cands, mode).tobytes() == expected.tobytes()



def _candidates_states(candidates, seed: int, n: int, preview: bool) -> list[np.ndarray]:
    """``n`` steps' states of every candidate (build_states), egos near the paths, random others."""
    rng = np.random.default_rng(seed)
    pts = np.concatenate([c.points for c in candidates])
    out = []
    for k in rng.integers(0, len(pts), n):
        x, y = pts[k] + rng.normal(0, 2.0, 2)
        e = np.array([x, y, rng.uniform(0, 12), rng.normal(0, 0.3), rng.uniform(-20, 20), rng.normal(0, 0.3),
                      rng.uniform(-0.5, 0.5), rng.uniform(-3, 1.5)])
        others = S.select_others(e, np.column_stack([rng.uniform(-80, 80, (25, 2)) + [x, y], rng.uniform(0, 15, 25),
                                                     rng.uniform(-20, 20, 25), rng.uniform(0.3, 12, (25, 2))]),
                                 rng.choice(["vehicle", "cyclist", "pedestrian"], 25))
        out.append(S.build_states(e, others, candidates, str(rng.choice(["pass", "stop"])), preview))
    return out


@pytest.mark.parametrize("xp", [NumpyOps, TorchTrigNumpyOps])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_candidates_input_is_network_input_bit_for_bit(candidates, xp, dtype) -> None:
    """The online decision normalises the rows' shared x_ego and x_other once (candidates_input):
    the same numbers as network_input of every row, bit for bit, with and without the preview and
    the lead summary, on the states build_states makes (some with someone in the corridor ahead)."""
    leads = 0
    for preview in (False, True):
        for states in _candidates_states(candidates, seed=11, n=60, preview=preview):
            data = states.astype(dtype)
            assert S.rows_share_ego_and_others(data)
            for lead in (False, True):
                expected = S.network_input(data, preview, lead, xp=xp)
                got = S.candidates_input(data, preview, lead, xp=xp)
                assert got.dtype == expected.dtype and got.shape == expected.shape
                assert got.tobytes() == expected.tobytes()
                assert got.flags.c_contiguous
                leads += lead and bool(got[0, -1] == 1.0)
    assert leads > 0


def test_candidates_input_on_random_shared_rows() -> None:
    """The same on random rows sharing x_ego and x_other: headings far beyond ±π, large and small
    positions, so the wrap and the ego frame are exercised everywhere."""
    rng = np.random.default_rng(4)
    for st in random_states(300, seed=5):
        st[S.PHI] = rng.uniform(-50.0, 50.0)
        S.others_block(st)[:, S.O_PHI] = rng.uniform(-50.0, 50.0, 16)
        st[:2] *= rng.choice([0.01, 1.0, 100.0])
        rows = np.concatenate([np.repeat(st[None], 3, 0), rng.normal(0.0, 5.0, (3, 12))], axis=1)
        rows[:, S.TRACK] = rng.normal(0.0, 3.0, (3, 4))
        data = rows.astype(np.float32)
        for lead in (False, True):
            expected = S.network_input(data, True, lead, xp=TorchTrigNumpyOps)
            assert S.candidates_input(data, True, lead, xp=TorchTrigNumpyOps).tobytes() == expected.tobytes()


def test_rows_share_ego_and_others() -> None:
    st = np.repeat(random_states(1)[0][None], 3, 0)
    st[:, S.TRACK] = np.arange(12.0).reshape(3, 4)  # x_track may differ
    assert S.rows_share_ego_and_others(st)
    assert S.rows_share_ego_and_others(st[:1])
    for column in (S.VX, S.OTHERS.start, S.OTHERS.stop - 1):
        other = st.copy()
        other[2, column] += 1e-9
        assert not S.rows_share_ego_and_others(other)
    other = st.copy()
    other[:, S.PX] = np.nan  # a NaN is never shared
    assert not S.rows_share_ego_and_others(other)


def test_the_path_preview_numpy_and_torch_agree_and_leave_the_108_values_alone() -> None:
    """build_states(..., preview=True) (online) and preview_torch (training) give the same 12 values:
    the path 5-20 m ahead in the ego's frame, its heading and v_ref there."""
    import torch

    from crossroads.intersections import catalogue
    from crossroads.sim.config import WorldConfig
    from crossroads.sim.traffic import NO_TRAFFIC
    from crossroads.sim.world import World

    with World(WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", demand=NO_TRAFFIC,
                           warmup_s=1.0)) as world:
        candidates, obs = tuple(world.candidates), world.reset(0)
    tensors = S.path_tensors(candidates, dtype=torch.float64)
    rng = np.random.default_rng(0)
    for trial in range(20):
        path = candidates[trial % len(candidates)]
        k = int(rng.integers(len(path.points)))
        ego = np.array(obs.ego, dtype=np.float64)
        ego[:2] = path.points[k] + rng.normal(0.0, 0.8, 2)
        ego[S.PHI] = path.heading[k] + rng.normal(0.0, 0.2)
        others = np.tile(S.pad_participant(ego), (S.N_OTHERS, 1))
        mode = ("pass", "stop")[trial % 2]
        states = S.build_states(ego, others, candidates, mode, preview=True)
        assert states.shape == (len(candidates), S.PREVIEW_STATE_DIM)
        assert np.array_equal(states[:, :STATE_DIM], S.build_states(ego, others, candidates, mode))
        egos = torch.as_tensor(np.tile(ego, (len(candidates), 1)))
        index = torch.arange(len(candidates))
        ref = S.reference_points_torch(tensors, egos[:, :2], index, mode == "stop")
        np.testing.assert_allclose(S.preview_torch(tensors, egos, ref, index, mode == "stop").numpy(),
                                   states[:, S.PREVIEW], atol=1e-9)



def _preview_with_numpy(candidates, ego: np.ndarray, mode: str) -> np.ndarray:
    """The path preview (C, 12) of build_states as numpy computes it: np.interp of each path's
    points at the distances ahead of the ego's foot, then preview_features."""
    refs = S.references(candidates, float(ego[S.PX]), float(ego[S.PY]), mode)
    st = S._stacked(tuple(candidates))
    i, w, _ = S._nearest(st, float(ego[S.PX]), float(ego[S.PY]))
    rows = np.arange(len(candidates))
    arc = st.s0[rows, i] + np.array(w) * st.ds[rows, i]
    ahead = np.empty((4, len(candidates), S.N_PREVIEW))
    for c, path in enumerate(candidates):
        s = np.asarray(path.s, np.float64)
        target = np.minimum(arc[c] + np.asarray(PREVIEW_DISTANCES_M), s[-1])
        values = (path.points[:, 0], path.points[:, 1], np.unwrap(path.heading), path.v_pass if mode == "pass" else path.v_stop)
        for row, value in enumerate(values):
            ahead[row, c] = np.interp(target, s, np.asarray(value, np.float64))
    assert refs.index.tolist() == list(i)
    heading = np.mod(ahead[2] + math.pi, 2.0 * math.pi) - math.pi
    return S.preview_features(np.broadcast_to(ego, (len(candidates), 8)), ahead[0], ahead[1], heading, ahead[3])


def test_the_path_preview_on_floats_is_numpys_bit_for_bit(candidates) -> None:
    """build_states works the preview out on Python floats: np.interp's and preview_features'
    numbers, bit for bit, for egos all along the paths, beyond their ends and before their starts."""
    rng = np.random.default_rng(12)
    pts = np.concatenate([c.points for c in candidates])
    others = np.tile(S.pad_participant(np.zeros(8)), (S.N_OTHERS, 1))
    tuple_candidates = tuple(candidates)
    for k in [*rng.integers(0, len(pts), 300), 0, len(pts) - 1]:
        ego = np.array([*(pts[k] + rng.normal(0.0, 3.0, 2)), 5.0, 0.0, rng.uniform(-10.0, 10.0), 0.0, 0.0, 0.0])
        for mode in ("pass", "stop"):
            states = S.build_states(ego, others, tuple_candidates, mode, preview=True)
            assert states[:, S.PREVIEW].tobytes() == _preview_with_numpy(candidates, ego, mode).tobytes()


def test_the_path_preview_sees_the_turn_ahead() -> None:
    """On the straight before a left turn's stop line, the points 15-20 m ahead lie to the left."""
    from crossroads.intersections import catalogue
    from crossroads.sim.config import WorldConfig
    from crossroads.sim.traffic import NO_TRAFFIC
    from crossroads.sim.world import World

    with World(WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", demand=NO_TRAFFIC,
                           warmup_s=1.0)) as world:
        path = world.candidates[0]
        obs = world.reset(0)
    ego = np.array(obs.ego, dtype=np.float64)
    k = int(np.searchsorted(path.s, path.s_stop_line - 5.0))
    ego[:2], ego[S.PHI] = path.points[k], path.heading[k]
    others = np.tile(S.pad_participant(ego), (S.N_OTHERS, 1))
    lateral = S.build_states(ego, others, [path], "pass", preview=True)[0, S.PREVIEW][:S.N_PREVIEW]
    assert abs(lateral[0]) < 0.05 and lateral[3] > lateral[2] > 0.5  # straight 5 m ahead, bending left beyond


def test_networks_with_the_preview_refuse_states_without_it() -> None:
    with pytest.raises(ValueError, match="path preview reads states of 120 values"):
        S.network_input(np.zeros((2, STATE_DIM)), preview=True)
    assert S.network_input(np.zeros((2, S.PREVIEW_STATE_DIM))).shape == (2, STATE_DIM)


def _ego_on_x_axis(speed: float) -> np.ndarray:
    """A state of an ego at the origin heading +x at ``speed``, every participant slot padded."""
    ego = np.array([0.0, 0.0, speed, 0.0, 0.0, 0.0, 0.0, 0.0])
    others = np.tile(S.pad_participant(ego), (S.N_OTHERS, 1))
    return np.concatenate([ego, np.zeros(4), others.ravel()])


def _put(state: np.ndarray, slot: int, row: list[float]) -> None:
    state[12 + 6 * slot: 18 + 6 * slot] = row


def test_lead_features_pick_the_nearest_participant_in_the_corridor_whatever_its_slot() -> None:
    from crossroads.constants import EGO_LENGTH_M, LEAD_LOOKAHEAD_M

    empty = _ego_on_x_axis(6.0)
    np.testing.assert_allclose(S.lead_features(empty), [1.0, 0.0, 0.0])
    state = empty.copy()
    _put(state, 0, [8.0, 3.5, 6.0, 0.0, 4.8, 1.8])   # nearest of all, but in the next lane
    _put(state, 1, [12.0, -9.0, 5.0, math.pi / 2, 4.8, 1.8])  # crossing, still to the right
    _put(state, 5, [30.0, 0.4, 2.0, 0.0, 4.8, 1.8])  # the car ahead, in a late slot
    _put(state, 12, [45.0, 0.0, 0.0, 0.0, 0.5, 0.5])  # a pedestrian in the corridor, farther
    gap = 30.0 - 2.4 - EGO_LENGTH_M / 2
    np.testing.assert_allclose(S.lead_features(state), [gap / LEAD_LOOKAHEAD_M, (6.0 - 2.0) / 10.0, 1.0])
    swapped = state.copy()  # the same scene, the car ahead moved to the first slot
    swapped[12:18], swapped[42:48] = state[42:48], state[12:18]
    np.testing.assert_allclose(S.lead_features(swapped), S.lead_features(state))
    _put(state, 7, [-10.0, 0.0, 8.0, 0.0, 4.8, 1.8])  # a follower does not count
    np.testing.assert_allclose(S.lead_features(state), S.lead_features(swapped))
    oncoming = empty.copy()
    _put(oncoming, 3, [15.0, 0.0, 5.0, math.pi, 4.8, 1.8])  # head-on: closing at both speeds
    assert S.lead_features(oncoming)[1] == pytest.approx((6.0 + 5.0) / 10.0)


def test_lead_features_are_pose_invariant_backend_free_and_differentiable() -> None:
    st = random_states(64)
    for k in range(0, 64, 4):  # a participant just ahead of every fourth ego
        phi = st[k, S.PHI]
        _put(st[k], 2, [st[k, 0] + 9.0 * math.cos(phi), st[k, 1] + 9.0 * math.sin(phi), 3.0, phi, 4.5, 1.8])
    lead = S.lead_features(st)
    assert lead.shape == (64, 3) and lead[::4, 2].all()
    np.testing.assert_allclose(S.lead_features(rigid(st, 1.3, -40.0, 250.0)), lead, atol=1e-9)
    t = torch.tensor(st, requires_grad=True)
    np.testing.assert_allclose(S.lead_features(t).detach().numpy(), lead, rtol=1e-9, atol=1e-9)
    S.lead_features(t)[:, 0].sum().backward()
    phi = t.detach()[::4, S.PHI]  # driving ahead, towards the lead, shrinks the gap
    assert (t.grad[::4, S.PX] * torch.cos(phi) + t.grad[::4, S.PY] * torch.sin(phi) < 0).all()
    x = S.network_input(st, lead=True)
    assert x.shape == (64, STATE_DIM + 3)
    np.testing.assert_allclose(x[:, STATE_DIM:], lead)


def _every_segment(st, x, y):
    """(i, w, d) of every segment searched, in plain numpy: each candidate's nearest segment (the
    first of equals), its foot's position w and the squared distance to the foot."""
    relx, rely = x - st.ax, y - st.ay
    t = (relx * st.abx + rely * st.aby) * st.inv_len2
    t = np.minimum(np.maximum(t, 0.0), 1.0)
    d = (relx - t * st.abx) ** 2 + (rely - t * st.aby) ** 2
    i = d.argmin(axis=1)
    rows = np.arange(len(i))
    return i.tolist(), t[rows, i].tolist(), d[rows, i].tolist()


def test_the_nearest_segments_are_those_of_the_plain_search(candidates) -> None:
    """_nearest (in-place numpy, for speed) gives the segments, positions and distances of the plain
    search, on points along the paths, off them, far from them and NaN."""
    rng = np.random.default_rng(11)
    st = S._stacked(tuple(candidates))
    pts = np.concatenate([c.points for c in candidates])
    for xy in [*(pts[rng.integers(0, len(pts), 200)] + rng.normal(0, 1.5, (200, 2))), *rng.uniform(-400, 400, (20, 2))]:
        x, y = float(xy[0]), float(xy[1])
        assert S._nearest(st, x, y) == _every_segment(st, x, y)
    assert S._nearest(st, math.nan, 0.0)[0] == _every_segment(st, math.nan, 0.0)[0]


def test_a_standing_ego_is_answered_from_the_last_search(candidates) -> None:
    """_nearest answers a point asked again (an ego standing still) from its last search: the same
    numbers as the plain search, in lists of the caller's own; other stacks or points search again."""
    st = S._stacked(tuple(candidates))
    x, y = (float(v) for v in candidates[0].points[40] + [0.3, -0.2])
    first = S._nearest(st, x, y)
    again = S._nearest(st, x, y)
    assert first == again == _every_segment(st, x, y)
    again[0].append(99)  # a caller changing its lists changes no later answer
    assert S._nearest(st, x, y) == first
    other = S._stacked((candidates[2], candidates[0]))
    assert S._nearest(other, x, y) == _every_segment(other, x, y)
    assert S._nearest(st, x + 1e-9, y) == _every_segment(st, x + 1e-9, y)


def test_the_common_stretch_of_the_candidates(candidates) -> None:
    """The candidates of one approach share their segments up to the junction: _stacked counts
    them (here 100 segments of the 3 left-turn paths), a lone path shares all its own, and paths
    apart share none."""
    st = S._stacked(tuple(candidates))
    assert 0 < st.shared < st.ax.shape[1]
    for c in candidates:  # the shared segments are the same floats in every path
        np.testing.assert_array_equal(c.points[:st.shared], candidates[0].points[:st.shared])
    assert not np.array_equal(candidates[1].points[st.shared + 1], candidates[0].points[st.shared + 1])
    assert S._stacked((candidates[2],)).shared == S._stacked((candidates[2],)).ax.shape[1]
    assert S._stacked((candidates[0], _shifted(candidates[0], 3.0))).shared == 0


def test_kind_codes_fill_the_slots_as_the_names_do() -> None:
    """The kinds given as codes (Perceived.kind_codes; −1: another kind, ignored) fill the slots with
    the rows a stable sort within each kind of the names gives, in the same order: more participants
    of a kind than its slots, fewer, none, and ties in distance (positions on a 1 m grid)."""
    rng = np.random.default_rng(13)
    names_and_codes = {"vehicle": 0, "cyclist": 1, "pedestrian": 2, "tram": -1}
    for n in (0, 1, 3, 17, 40, 150):
        for _ in range(25):
            ego = np.array([*rng.integers(-5, 5, 2).astype(float), 5.0, 0.0, rng.uniform(-3, 3), 0.0, 0.0, 0.0])
            obs = np.column_stack([rng.integers(-12, 12, (n, 2)).astype(float), rng.uniform(-3, 3, (n, 4))])
            names = rng.choice(list(names_and_codes), n, p=[0.5, 0.25, 0.15, 0.1]) if n else np.zeros(0, "<U10")
            codes = np.array([names_and_codes[k] for k in names], dtype=np.int8)
            expected = _select_others_per_kind(ego, obs, names)
            assert S.select_others(ego, obs, codes).tobytes() == expected.tobytes()
            assert S.select_others(ego, obs, names).tobytes() == expected.tobytes()
            assert S.selected_rows(ego, obs, codes).tolist() == S.selected_rows(ego, obs, names).tolist()


def _shifted(c, dy):
    """Candidate ``c`` moved by ``dy`` metres along y (a parallel path)."""
    return dataclasses.replace(c, points=c.points + np.array([0.0, dy]))


def test_tracked_state_is_the_row_of_build_states(candidates) -> None:
    """tracked_state builds one state alone: the row of build_states' states it names, bit for bit,
    and for path=None the row np.hypot(Δx, Δy).argmin() picks, also where two candidates are at the
    same distance (a copy of a path: the first; the ego on the stretch the candidates share) or
    nearly (between two parallel paths: numpy's hypot decides)."""
    rng = np.random.default_rng(12)
    twin = dataclasses.replace(candidates[1])  # the same points, another object
    parallel = (candidates[0], _shifted(candidates[0], 3.0))
    sets = [tuple(candidates), (candidates[1], twin, candidates[0]), parallel, (candidates[2],)]
    checked = ties = common = 0
    for cands in sets:
        pts = np.concatenate([c.points for c in cands])
        for k in range(40):
            x, y = pts[rng.integers(0, len(pts))] + rng.normal(0, 1.5, 2)
            if cands is parallel and k % 2:  # between the two: equidistant, or nearly
                x, y = cands[0].points[rng.integers(0, len(cands[0].points))] + [0.0, 1.5]
                y += [0.0, 1e-12, 1e-9, 1e-7, 1e-5, 1e-3][k % 6] * rng.choice([-1.0, 1.0])
            ego = np.array([x, y, rng.uniform(0, 12), 0.1, rng.uniform(-4, 4), 0.02, 0.01, 0.3])
            n = int(rng.integers(0, 30))
            obs = np.column_stack([rng.uniform(-40, 40, (n, 2)) + [x, y], rng.uniform(-3, 3, (n, 4))])
            kinds = rng.choice(["vehicle", "cyclist", "pedestrian", "tram"], n)
            others = S.select_others(ego, obs, kinds)
            st = S._stacked(cands)
            i, w, _ = S._nearest(st, x, y)
            common += len(cands) > 1 and i[0] < st.shared and len(set(i)) == 1 and len(set(w)) == 1
            for mode in ("pass", "stop"):
                for preview in (False, True):
                    states = S.build_states(ego, others, cands, mode, preview)
                    hyp = np.hypot(states[:, S.DX], states[:, S.DY])
                    nearest = int(hyp.argmin())
                    ties += int(np.sum(hyp == hyp[nearest]) > 1)
                    for path in (None, *range(len(cands))):
                        index, state = S.tracked_state(ego, obs, kinds, cands, mode, path, preview)
                        assert index == (nearest if path is None else path)
                        assert state.tobytes() == states[index].tobytes()
                        checked += 1
    assert checked > 1000 and ties > 20 and common > 10  # common: every foot on the shared stretch
