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

import numpy as np

from crossroads.constants import JERK_MAX, PENALTY_RHO, STATE_DIM, STEER_RATE_MAX
from crossroads.idc.constraints import (
    EGO_CIRCLE_OFFSET_M,
    EGO_RADIUS_M,
    ROAD_LATERAL_BOUND_M,
    SAFETY_MARGIN_M,
    penalty,
    road_constraints,
    safety_constraints,
)
from crossroads.idc.state import DPHI, DY, O_L, O_PX, O_PY, O_W, PX, PY, others_block
from crossroads.idc.utility import utility

DEFAULT_OUTCOME_REWARDS = {"passed": 100.0, "collision": -100.0, "red_light": -100.0,
                           "off_road": -100.0, "timeout": 0.0, "error": -100.0}
_ACTION_LIMITS = np.array([STEER_RATE_MAX, JERK_MAX])


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


def safety_penalty(state: np.ndarray) -> float:
    """φ of :func:`~crossroads.idc.constraints.safety_constraints` of one state, exactly; 0 without
    computing the 56 constraints when every participant is out of reach (most steps), which saves
    ~120 µs a step. Out of reach: g ≤ (ego circle offset + radius) + (the other's circle offset +
    radius ≤ (L + W)/2) + margin − centre distance < 0 for every circle pair."""
    o = others_block(state)
    distance = np.hypot(o[:, O_PX] - state[PX], o[:, O_PY] - state[PY])
    reach = EGO_CIRCLE_OFFSET_M + EGO_RADIUS_M + 0.5 * (o[:, O_L] + o[:, O_W]) + SAFETY_MARGIN_M
    if (distance > reach).all():
        return 0.0
    return float(penalty(safety_constraints(state)))


def road_penalty(state: np.ndarray) -> float:
    """φ of :func:`~crossroads.idc.constraints.road_constraints` of one state (from its x_track),
    exactly; 0 at once when both circle centres are within the bound (|Δy| + offset·|sin Δφ|)."""
    dy, dphi = float(state[DY]), float(state[DPHI])
    if abs(dy) + EGO_CIRCLE_OFFSET_M * abs(math.sin(dphi)) <= ROAD_LATERAL_BOUND_M:
        return 0.0
    return float(penalty(road_constraints(state)))


@dataclass(frozen=True)
class RewardParts:
    """One step's reward and what it is made of (``info`` carries them)."""

    utility: float
    penalty: float
    outcome: float

    @property
    def total(self) -> float:
        return self.outcome - self.utility - self.penalty


def step_reward(config: RewardConfig, state: np.ndarray, action: np.ndarray, next_state: np.ndarray,
                outcome: str | None) -> RewardParts:
    """The reward of one step (module docstring); ``state``/``next_state`` of the tracked path."""
    applied = np.clip(np.asarray(action, dtype=np.float64), -_ACTION_LIMITS, _ACTION_LIMITS)
    l_value, _ = utility(state[:STATE_DIM], applied)
    nxt = next_state[:STATE_DIM]
    phi = safety_penalty(nxt) + road_penalty(nxt)
    bonus = 0.0 if outcome is None else config.outcome_rewards[outcome]
    return RewardParts(float(l_value), config.penalty_weight * phi, bonus)
