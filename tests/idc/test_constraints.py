"""Safety and road constraints and the exterior penalty (SPEC §4)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from crossroads.constants import DT_S, EGO_LENGTH_M, EGO_WIDTH_M, HORIZON_T, XI_RANGES
from crossroads.idc import constraints as C
from crossroads.idc import state as S
from crossroads.sim.ego import ego_step
from crossroads.sim.other import other_step


def scene(ego: np.ndarray, obs=np.zeros((0, 6)), kinds=()) -> np.ndarray:
    st = np.zeros(108)
    st[S.EGO] = ego
    st[S.OTHERS] = S.select_others(ego, np.asarray(obs, float).reshape(-1, 6), np.array(kinds)).ravel()
    return st


EGO = np.array([5.0, -3.0, 8.0, 0.0, 0.6, 0.0, 0.0, 0.0])


def test_padded_participants_never_bind_over_the_horizon() -> None:
    st = scene(EGO)
    g = C.safety_constraints(st)
    assert g.shape == (C.N_SAFETY,) == (56,) and (g < 0).all() and C.penalty(g) == 0.0
    # worst case: pads pushed straight at the ego by the adversary, the ego driving back at them
    ego = EGO.copy()
    ego[4] += math.pi
    ego[2] = 15.0
    others = S.others_block(st).copy()
    for _ in range(HORIZON_T):
        to_ego = np.arctan2(ego[1] - others[:, 1], ego[0] - others[:, 0])
        xi = np.column_stack([XI_RANGES["x"][1] * np.cos(to_ego), XI_RANGES["y"][1] * np.sin(to_ego),
                              np.full(16, XI_RANGES["v"][1]), np.zeros(16)])
        others = other_step(others, 0.0, xi)
        others[:, 3] = to_ego
        ego = ego_step(ego, [0.0, 0.0])
        st2 = np.concatenate([ego, np.zeros(4), others.ravel()])
        assert C.penalty(C.safety_constraints(st2)) == 0.0


def test_overlapping_vehicle_is_penalised_and_slots_are_ordered() -> None:
    near = [EGO[0] + 1.0, EGO[1], 3.0, 0.0, 4.5, 1.8]
    st = scene(EGO, [near], ["vehicle"])
    g = C.safety_constraints(st)
    assert (g[:4] > 0).any() and (g[4:] < 0).all() and C.penalty(g) > 0
    assert C.penalty(g) == pytest.approx(np.sum(np.maximum(g[:4], 0.0) ** 2))
    far = [EGO[0] + 20.0, EGO[1], 3.0, 0.0, 4.5, 1.8]
    assert C.penalty(C.safety_constraints(scene(EGO, [far], ["vehicle"]))) == 0.0
    ped = [EGO[0], EGO[1] + 0.5, 1.0, 0.0, 0.5, 0.5]
    g = C.safety_constraints(scene(EGO, [ped], ["pedestrian"]))
    assert (g[48:50] > 0).all() and (g[:48] < 0).all() and (g[50:] < 0).all()
    cyc = [EGO[0], EGO[1] + 1.0, 1.0, 0.0, 1.8, 0.6]
    g = C.safety_constraints(scene(EGO, [cyc], ["cyclist"]))
    assert (g[32:36] > 0).any() and (g[:32] < 0).all() and (g[36:] < 0).all()


def test_circles_span_the_ego() -> None:
    """Radius W/2 at ±(L − W)/2: the circles reach both ends of the body and its full width; with
    the safety margin, even a pedestrian beside the middle of the car binds the constraint."""
    ex, ey, r = C.ego_circles(EGO)
    assert r == pytest.approx(EGO_WIDTH_M / 2)
    c, s = math.cos(EGO[4]), math.sin(EGO[4])
    for lx in (-EGO_LENGTH_M / 2, EGO_LENGTH_M / 2):  # front and rear ends
        px, py = EGO[0] + c * lx, EGO[1] + s * lx
        assert np.min(np.hypot(ex - px, ey - py)) <= r + 1e-9
    for centre in range(2):  # the full width at each circle's centre
        for ly in np.linspace(-EGO_WIDTH_M / 2, EGO_WIDTH_M / 2, 9):
            px, py = ex[centre] - s * ly, ey[centre] + c * ly
            assert np.hypot(ex[centre] - px, ey[centre] - py) <= r + 1e-9
    beside_middle = EGO[:2] + 1.2 * np.array([-s, c])  # a pedestrian 0.2 m off the side
    st = scene(EGO, [[*beside_middle, 0.0, 0.0, 0.5, 0.5]], ["pedestrian"])
    assert C.penalty(C.safety_constraints(st)) > 0.0


def test_cars_in_neighbouring_lanes_do_not_violate() -> None:
    """Side by side in 3.5 m lanes, same heading: no penalty (they are not in conflict)."""
    beside = EGO[:2] + 3.5 * np.array([-math.sin(EGO[4]), math.cos(EGO[4])])
    st = scene(EGO, [[*beside, 8.0, EGO[4], EGO_LENGTH_M, EGO_WIDTH_M]], ["vehicle"])
    assert C.penalty(C.safety_constraints(st)) == 0.0


def test_margin_and_threshold() -> None:
    # two identical cars side by side, centres d apart laterally: g = 2r + margin − d
    d = 4.0
    other_xy = EGO[:2] + d * np.array([-math.sin(EGO[4]), math.cos(EGO[4])])
    st = scene(EGO, [[*other_xy, 0.0, EGO[4], EGO_LENGTH_M, EGO_WIDTH_M]], ["vehicle"])
    g = C.safety_constraints(st, safety_margin_m=0.25)
    assert g[0] == pytest.approx(2 * C.EGO_RADIUS_M + 0.25 - d, abs=1e-6)


def test_road_constraints() -> None:
    st = scene(EGO)
    st[S.TRACK] = [0.0, 0.0, 0.0, 0.0]
    g = C.road_constraints(st)
    assert g.shape == (4,) and (g < 0).all() and C.penalty(g) == 0.0
    st[S.DY] = C.ROAD_LATERAL_BOUND_M + 0.5
    g = C.road_constraints(st)
    assert g[0] == pytest.approx(0.5) and g[2] == pytest.approx(0.5) and C.penalty(g) == pytest.approx(0.5)
    # with an explicit reference: same numbers as from x_track
    ego = EGO.copy()
    ref = (1.0, 2.0, 0.3)
    st[S.EGO] = ego
    st[S.TRACK] = S.tracking_error(ego, *ref, 0.0)
    np.testing.assert_allclose(C.road_constraints(st, *ref), C.road_constraints(st), atol=1e-12)


def test_penalty_is_exactly_the_papers() -> None:
    g = np.array([[-1.0, 0.0, 2.0], [0.5, -3.0, 0.0]])
    np.testing.assert_allclose(C.penalty(g), [4.0, 0.25])


def test_numpy_equals_torch_and_gradients() -> None:
    rng = np.random.default_rng(0)
    st = np.zeros((6, 108))
    st[:, :8] = rng.uniform([-5, -5, 0, -1, -3, -1, -0.4, -3], [5, 5, 10, 1, 3, 1, 0.4, 1.5], (6, 8))
    st[:, 8:12] = rng.normal(size=(6, 4))
    o = S.others_block(st)
    o[..., :2] = rng.uniform(-8, 8, (6, 16, 2))
    o[..., 2:4] = rng.uniform(-3, 3, (6, 16, 2))
    o[..., 4:] = rng.uniform(0.3, 5, (6, 16, 2))
    g, r = C.safety_constraints(st), C.road_constraints(st)
    t = torch.tensor(st, requires_grad=True)
    gt, rt = C.safety_constraints(t), C.road_constraints(t)
    np.testing.assert_allclose(gt.detach().numpy(), g, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(rt.detach().numpy(), r, rtol=1e-9, atol=1e-9)
    assert C.penalty(g).max() > 0
    (C.penalty(gt) + C.penalty(rt)).sum().backward()
    assert torch.isfinite(t.grad).all() and t.grad[:, :2].abs().sum() > 0
    ref = (torch.zeros(6, dtype=torch.float64), torch.zeros(6, dtype=torch.float64), torch.full((6,), 0.2, dtype=torch.float64))
    np.testing.assert_allclose(C.road_constraints(t, *ref).detach().numpy(),
                               C.road_constraints(st, *(x.numpy() for x in ref)), atol=1e-12)
    # coincident centres stay differentiable
    z = torch.zeros(108, dtype=torch.float64)
    z[S.OTHERS.start + 4: S.OTHERS.start + 6] = torch.tensor([4.0, 2.0])
    z.requires_grad_(True)
    C.penalty(C.safety_constraints(z)).backward()
    assert torch.isfinite(z.grad).all()
    assert DT_S > 0


def test_deepest_by_slot_is_each_participants_largest_value() -> None:
    g = np.random.default_rng(3).normal(size=(5, C.N_SAFETY))
    got = C.deepest_by_slot(g)
    slots = np.array(C.SAFETY_SLOT)
    assert got.shape == (5, 16)
    for slot in range(16):
        np.testing.assert_array_equal(got[:, slot], g[:, slots == slot].max(axis=1))
