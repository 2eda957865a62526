"""The utility l (SPEC §4)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from crossroads.constants import UTILITY_WEIGHTS
from crossroads.idc import state as S
from crossroads.idc.utility import utility


def test_each_term() -> None:
    st = np.zeros(108)
    total, parts = utility(st, np.zeros(2))
    assert total == 0.0 and set(parts) == set(UTILITY_WEIGHTS)
    where = {"dv": S.DV, "dx": S.DX, "dy": S.DY, "dphi": S.DPHI, "omega": S.OMEGA, "delta": S.DELTA, "a": S.ACC}
    for name, k in where.items():
        s = np.zeros(108)
        s[k] = 2.0
        total, parts = utility(s, np.zeros(2))
        assert total == pytest.approx(4.0 * UTILITY_WEIGHTS[name]) and parts[name] == total
    total, parts = utility(np.zeros(108), np.array([2.0, -3.0]))
    assert parts["ddelta"] == pytest.approx(4 * UTILITY_WEIGHTS["ddelta"]) and parts["da"] == pytest.approx(9 * UTILITY_WEIGHTS["da"])
    assert total == pytest.approx(parts["ddelta"] + parts["da"])
    # ego position, speed, heading and the others do not enter l
    s = np.zeros(108)
    s[[S.PX, S.PY, S.VX, S.VY, S.PHI]] = 5.0
    s[S.OTHERS] = 3.0
    assert utility(s, np.zeros(2))[0] == 0.0


def test_numpy_equals_torch_and_gradients() -> None:
    rng = np.random.default_rng(0)
    st, u = rng.normal(size=(4, 3, 108)), rng.normal(size=(4, 3, 2))
    total, parts = utility(st, u)
    assert total.shape == (4, 3)
    ut = torch.tensor(u, requires_grad=True)
    tt, pt = utility(torch.tensor(st), ut)
    np.testing.assert_allclose(tt.detach().numpy(), total, rtol=1e-9, atol=1e-9)
    for k in parts:
        np.testing.assert_allclose(pt[k].detach().numpy(), parts[k], rtol=1e-9, atol=1e-9)
    tt.sum().backward()
    np.testing.assert_allclose(ut.grad[..., 1].numpy(), 2 * UTILITY_WEIGHTS["da"] * u[..., 1])
