"""The Gymnasium environment's reward: the paper's cost, negated, plus the episode's outcome.

Every step, for the action u_t taken in state s_t (of the tracked path) that led to s_{t+1}::

    r_t = −( l(s_t, u_t) + ρ · φ(g(s_{t+1})) ) + outcome bonus (last step only)

* l: the utility of SPEC §4 (:mod:`crossroads.idc.utility`: tracking errors, steering, acceleration
  and the action's size, the paper's weights), on the action as the ego applies it (clipped);
* φ(g): the exterior penalty of the safety constraints against the 16 observed participants and of
  the road constraint (:mod:`crossroads.idc.constraints`), on the state the step led to, weighted by
  ρ = 15 (the paper's penalty weight) — so a near miss costs before a collision ends the episode;
* the outcome (choice, not the paper's, which has no episodes to end): +100 for passing, −100 for a
  collision, a red-light violation or leaving the road, 0 for a timeout (the utility has charged
  for the time by then), −100 for ``error`` (SUMO lost the ego: it drove far off its route).
  Timeouts are *truncations* in Gymnasium's sense; the others terminate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from crossroads.constants import (
    JERK_MAX,
    OTHER_STATE_DIM,
    PENALTY_RHO,
    STATE_DIM,
    STEER_RATE_MAX,
    UTILITY_WEIGHTS,
)
from crossroads.idc.constraints import (
    EGO_CIRCLE_OFFSET_M,
    EGO_RADIUS_M,
    ROAD_LATERAL_BOUND_M,
    SAFETY_MARGIN_M,
    TWO_CIRCLE_SLOTS,
    penalty,
    road_constraints,
    safety_constraints,
)
from crossroads.idc.state import (
    ACC,
    DELTA,
    DPHI,
    DV,
    DX,
    DY,
    N_OTHERS,
    O_L,
    O_PX,
    O_PY,
    O_W,
    OMEGA,
    OTHERS,
    PHI,
    PX,
    PY,
    TRACK,
)

DEFAULT_OUTCOME_REWARDS = {"passed": 100.0, "collision": -100.0, "red_light": -100.0,
                           "off_road": -100.0, "timeout": 0.0, "error": -100.0}
# what each utility weight multiplies (as idc.utility): (True: the state's value at the index; False:
# the action's), and the terms in the order idc.utility sums them, UTILITY_WEIGHTS' order
_UTILITY_SOURCES = {"dv": (True, DV), "dx": (True, DX), "dy": (True, DY), "dphi": (True, DPHI),
                    "omega": (True, OMEGA), "delta": (True, DELTA), "a": (True, ACC),
                    "ddelta": (False, 0), "da": (False, 1)}
_UTILITY_TERMS = tuple((UTILITY_WEIGHTS[name], *_UTILITY_SOURCES[name]) for name in UTILITY_WEIGHTS)


@dataclass(frozen=True)
class RewardConfig:
    """Weights of the reward (module docstring); every field may be changed per environment."""

    penalty_weight: float = PENALTY_RHO  # ρ of the constraint penalty
    outcome_rewards: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_OUTCOME_REWARDS))

    def __post_init__(self) -> None:
        if not (np.isfinite(self.penalty_weight) and self.penalty_weight >= 0.0):
            raise ValueError(f"RewardConfig.penalty_weight must be a finite number >= 0, got {self.penalty_weight}")
        unknown = set(self.outcome_rewards) - set(DEFAULT_OUTCOME_REWARDS)
        missing = set(DEFAULT_OUTCOME_REWARDS) - set(self.outcome_rewards)
        if unknown or missing:
            raise ValueError(f"RewardConfig.outcome_rewards needs exactly the outcomes "
                             f"{', '.join(DEFAULT_OUTCOME_REWARDS)}"
                             + (f"; unknown: {', '.join(sorted(unknown))}" if unknown else "")
                             + (f"; missing: {', '.join(sorted(missing))}" if missing else ""))


# Which slots have two circles (vehicles, cyclists) and which one (pedestrians), for safety_penalty
_TWO_CIRCLES = len(TWO_CIRCLE_SLOTS)
# [m] every ego circle's reach beyond the distance of its centre to the ego's: offset + radius + margin
_EGO_REACH_M = EGO_CIRCLE_OFFSET_M + EGO_RADIUS_M + SAFETY_MARGIN_M
# per slot, a bound on a participant's circle offset + radius per metre of max(|L|, |W|): a vehicle's
# or cyclist's is max(L, W)/2 exactly; a pedestrian's radius √(L²/4 + W²/4) ≤ max(|L|, |W|)·√2/2
_SLOT_REACH = (0.5,) * _TWO_CIRCLES + (math.sqrt(0.5),) * (N_OTHERS - _TWO_CIRCLES)
_SLOT_STARTS = tuple(range(OTHERS.start, STATE_DIM, OTHER_STATE_DIM))  # each slot's first index in a state
_PEDESTRIANS_START = _SLOT_STARTS[_TWO_CIRCLES]
# [m] what the bounds and the screening leave for rounding (and √(x + 1e-12) ≤ √x + 1e-6 of the
# constraints' ε): a value of g the screening puts below −_SLACK_M is negative in
# safety_constraints' own arithmetic, whose rounding errors are ~1e-13 m at intersection scale
_SLACK_M = 1e-5
_SCREEN_REACH_M = _EGO_REACH_M + _SLACK_M  # (the sum the screening starts from, as it adds it first)
# slices of a state's values: every slot's p_x, p_y, L, W
_XS, _YS, _LS, _WS = (slice(OTHERS.start + k, STATE_DIM, OTHER_STATE_DIM) for k in (O_PX, O_PY, O_L, O_W))


def safety_penalty(state: np.ndarray) -> float:
    """φ of :func:`~crossroads.idc.constraints.safety_constraints` of one state, exactly, computing
    those 56 constraints only when one of them may be violated (on no step of the nominal left turns
    measured: they cost ~75 µs a state, the screening ~7 µs). φ is exactly 0 when every g < 0; the
    screening shows that without them, on Python floats:

    1. the participants out of reach: g ≤ (ego circle offset + radius + margin) + (the other's
       offset + radius ≤ max(|L|, |W|)/2, √2·max(|L|, |W|)/2 for a pedestrian) − the distance of the
       centres, by the triangle inequality;
    2. for the few within reach, every circle pair's g (the same formula, rounded differently by
       at most ~1e-13 m).

    Either shows every g < −_SLACK_M, or the constraints are computed (and φ is theirs, NaN
    included)."""
    s = np.asarray(state, dtype=np.float64)[:STATE_DIM]
    return _safety_penalty(s, s.tolist())


def _safety_penalty(state: np.ndarray, values: list[float]) -> float:
    """:func:`safety_penalty` of ``state`` (108,), whose values are ``values`` (its ``tolist()``)."""
    px, py = values[PX], values[PY]
    near = []
    # each slot's x, y, L, W taken by slices of the values (the same floats, fewer index sums)
    for start, x, y, length, width, scale in zip(_SLOT_STARTS, values[_XS], values[_YS], values[_LS], values[_WS],
                                                 _SLOT_REACH):
        dx, dy = x - px, y - py
        reach = _SCREEN_REACH_M + scale * max(abs(length), abs(width))
        if not dx * dx + dy * dy > reach * reach:  # (not >: a NaN goes on to the constraints)
            near.append(start)
    if not near:
        return 0.0
    phi = values[PHI]
    ex, ey = EGO_CIRCLE_OFFSET_M * math.cos(phi), EGO_CIRCLE_OFFSET_M * math.sin(phi)
    ego = ((px - ex, py - ey), (px + ex, py + ey))
    reach = EGO_RADIUS_M + SAFETY_MARGIN_M + _SLACK_M
    for start in near:
        ox, oy, _, ophi, length, width = values[start: start + OTHER_STATE_DIM]
        if start < _PEDESTRIANS_START:
            off = max(length - width, 0.0) / 2.0
            cx, cy = off * math.cos(ophi), off * math.sin(ophi)
            circles = ((ox - cx, oy - cy, width / 2.0), (ox + cx, oy + cy, width / 2.0))
        else:
            circles = ((ox, oy, math.sqrt(length * length / 4.0 + width * width / 4.0 + 1e-12)),)
        for x, y, radius in circles:
            for gx, gy in ego:
                if not math.hypot(x - gx, y - gy) >= radius + reach:  # g > −_SLACK_M (or NaN): compute them
                    return float(penalty(safety_constraints(state)))
    return 0.0


def road_penalty(state: np.ndarray) -> float:
    """φ of :func:`~crossroads.idc.constraints.road_constraints` of one state (from its x_track),
    exactly; 0 at once when both circle centres are within the bound (|Δy| + offset·|sin Δφ|)."""
    s = np.asarray(state, dtype=np.float64)[:STATE_DIM]
    return _road_penalty(s, float(s[DY]), float(s[DPHI]))


def _road_penalty(state: np.ndarray, dy: float, dphi: float) -> float:
    """:func:`road_penalty` of ``state`` (108,), whose Δy and Δφ are ``dy``, ``dphi``."""
    if abs(dy) + EGO_CIRCLE_OFFSET_M * abs(math.sin(dphi)) <= ROAD_LATERAL_BOUND_M:
        return 0.0
    return float(penalty(road_constraints(state)))


class RewardParts(NamedTuple):
    """One step's reward and what it is made of (``info`` carries them)."""

    utility: float
    penalty: float
    outcome: float

    @property
    def total(self) -> float:
        return self.outcome - self.utility - self.penalty


def step_utility(state: np.ndarray, applied: tuple[float, float]) -> float:
    """l(s, u) of :func:`crossroads.idc.utility.utility` for one float64 state and a (clipped)
    action, on Python floats: the same products w·(x·x) summed in the same order from 0, so the
    same number, without ~20 numpy calls on 0-d arrays."""
    values = state[:TRACK.stop].tolist()
    total = 0.0
    for weight, of_state, index in _UTILITY_TERMS:
        x = values[index] if of_state else applied[index]
        total += weight * (x * x)
    return total


def step_reward(config: RewardConfig, state: np.ndarray, action: np.ndarray, next_state: np.ndarray,
                outcome: str | None) -> RewardParts:
    """The reward of one step (module docstring); ``state``/``next_state`` of the tracked path (in
    float64: other dtypes are converted first)."""
    steer, jerk = np.asarray(action, dtype=np.float64).reshape(2).tolist()
    return reward_parts(config, np.asarray(state, dtype=np.float64), steer, jerk,
                        np.asarray(next_state, dtype=np.float64), outcome)


def reward_parts(config: RewardConfig, state: np.ndarray, steer: float, jerk: float, next_state: np.ndarray,
                 outcome: str | None) -> RewardParts:
    """:func:`step_reward` of float64 states and the action's two numbers (the environment's step)."""
    # np.clip's min(max(x, lo), hi), on the two floats
    applied = (min(max(steer, -STEER_RATE_MAX), STEER_RATE_MAX), min(max(jerk, -JERK_MAX), JERK_MAX))
    l_value = step_utility(state, applied)
    nxt = next_state[:STATE_DIM]
    values = nxt.tolist()
    phi = _safety_penalty(nxt, values) + _road_penalty(nxt, values[DY], values[DPHI])
    bonus = 0.0 if outcome is None else config.outcome_rewards[outcome]
    return RewardParts(l_value, config.penalty_weight * phi, bonus)
