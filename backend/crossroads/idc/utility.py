"""The utility l(s, u) of the paper (SPEC §4, Sec. IV-C), weights from ``constants.UTILITY_WEIGHTS``::

    l = 0.03 Δv² + 0.8 Δx² + 0.8 Δy² + 30 Δφ² + 0.02 ω² + 5 δ² + 0.05 a² + 0.4 Δδ² + 0.1 Δa²

Δx, Δy, Δv, Δφ from x_track, ω, δ, a from x_ego (see :mod:`crossroads.idc.state`), Δδ, Δa the action.
"""

from __future__ import annotations

from typing import Any

from crossroads.arrays import ops
from crossroads.constants import UTILITY_WEIGHTS
from crossroads.idc.state import ACC, DELTA, DPHI, DV, DX, DY, OMEGA

_STATE_TERMS = {"dv": DV, "dx": DX, "dy": DY, "dphi": DPHI, "omega": OMEGA, "delta": DELTA, "a": ACC}
_ACTION_TERMS = {"ddelta": 0, "da": 1}
assert set(_STATE_TERMS) | set(_ACTION_TERMS) == set(UTILITY_WEIGHTS)


def utility(state: Any, action: Any) -> tuple[Any, dict[str, Any]]:
    """``(l[...], parts)`` for ``state[..., 108]`` and ``action[..., 2]`` (numpy or torch).

    ``parts`` maps each key of ``UTILITY_WEIGHTS`` to its weighted term w·x² (same shape as l);
    l is their sum. The action is taken as given (clip it first if it may lie outside its range).
    """
    xp = ops(state, action)
    state = xp.asarray(state, like=state)
    action = xp.asarray(action, like=state)
    parts: dict[str, Any] = {}
    for name, k in _STATE_TERMS.items():
        parts[name] = UTILITY_WEIGHTS[name] * state[..., k] ** 2
    for name, k in _ACTION_TERMS.items():
        parts[name] = UTILITY_WEIGHTS[name] * action[..., k] ** 2
    total = sum(parts[name] for name in UTILITY_WEIGHTS)
    return total, parts
