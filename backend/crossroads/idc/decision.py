"""Online IDC decision (SPEC §4, §7; paper eq. "apply value policy").

Every step: the traffic-light logic picks the speed mode; the state of every candidate path is
built in that mode and the batch goes through the value network; the path of least value is
τ* = argmin_τ v_w(s(τ)) (a near-tie goes to the first path); the driving policy's mean action for
s(τ*) is the command.

The networks are plain torch modules (anything with the shapes of :mod:`crossroads.rl.neural_nets`),
so this module does not depend on the training code: a trained model's networks are loaded by the
caller (``load_controller`` of :mod:`crossroads.evaluation.policies`, through ``rl.checkpoint``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch
from torch import nn

from crossroads.arrays import TorchTrigNumpyOps
from crossroads.constants import ACCEL_MAX, ACCEL_MIN, EGO_LENGTH_M, JERK_MAX
from crossroads.idc.controller import Decision, SpeedMode
from crossroads.idc.crosswalks import CrossingSpan, can_stand_short_of, claims_ahead, crossing_spans, nearest_claimed
from crossroads.idc.lights import light_holds_at_line, speed_mode_from
from crossroads.idc.observed import observed_others
from crossroads.idc.shield import shield_action
from crossroads.idc.state import (
    build_states,
    candidates_input,
    network_input,
    rows_share_ego_and_others,
    select_others,
)
from crossroads.planning import CandidatePath
from crossroads.sim.ego import ego_step_floats
from crossroads.sim.observation import Observation


# [0.1 s] the crossing the shield braked for stays its line until no one has claimed it for this
# many steps in a row, and only while the ego's light is green (:meth:`IdcController._crosswalk`).
# Why hold it: the line used to last only while full braking could still stand 0.5 m short; the
# policy accelerated on every step the shield let it (jerk-limited braking lost ~0.45 m/s² a
# step), a claim flickered off for a step on the pedestrians' noise, the ego slid past the point of
# standing short, and braking for the pedestrians stopped it 1.4–5.1 m onto the exit crosswalk,
# where they walked into it (6 of the 35 collisions of 200 nominal left turns, 150 s timeout; seed
# 896230294 at 60 s). Why green only: held inside the junction past its green, the ego was hit by
# the cross traffic SUMO lets go (4 more collisions at 150 s, seeds 1092899071, 154812432).
# docs/tried/shield.md, "Holding a crossing it braked for"
HELD_CROSSING_RELEASE_STEPS = 10

InputFunction = Callable[[torch.Tensor], torch.Tensor]  # a network on states already normalised


class IdcController:
    """Value network picks the path, driving policy tracks it (mean action); with ``shield``, the
    safety shield (:mod:`crossroads.idc.shield`) checks that action (off by default: not the paper's)."""

    def __init__(self, policy: nn.Module, value: nn.Module, name: str = "idc", shield: bool = False) -> None:
        self.policy = policy.eval()
        self.value = value.eval()
        self.name = name
        self._dtype = next(value.parameters()).dtype
        self._numpy_dtype = {torch.float32: np.float32, torch.float64: np.float64}.get(self._dtype)
        self._candidates: tuple[CandidatePath, ...] = ()
        self.shield = shield
        self._shield_braked = False  # the shield's verdict last step: it releases with a margin (idc.shield)
        self._spans: dict[int, tuple[CrossingSpan, ...]] = {}  # per candidate: its crossings (idc.crosswalks)
        self._held_crossing: tuple[int, CrossingSpan] | None = None  # (path, crossing) the shield braked for
        self._unclaimed_steps = 0  # steps in a row no one has claimed the held crossing
        # networks built with the path preview read 120-value states (crossroads.idc.state)
        self.preview = bool(getattr(policy, "preview", False))
        # the torch networks of crossroads.rl.neural_nets normalise their input (network_input)
        # themselves; when the two read it alike, a decision normalises its candidates once for both
        self._shared_input = (hasattr(value, "value_of_input") and hasattr(policy, "mean_action_of_input")
                              and getattr(policy, "low", None) is not None and policy.low.dtype == self._dtype
                              and self._numpy_dtype is not None
                              and (policy.preview, policy.lead) == (value.preview, value.lead))
        self._value_of_input, self._action_of_input = self._input_functions()

    def reset(self, candidates: Sequence[CandidatePath]) -> None:
        self._candidates = tuple(candidates)
        self._shield_braked = False
        self._spans = {}
        self._held_crossing = None
        self._unclaimed_steps = 0
        self._value_of_input, self._action_of_input = self._input_functions()  # the parameters as they are now

    def _input_functions(self) -> tuple[InputFunction, InputFunction]:
        """What :meth:`decide_states` calls on the normalised candidates (with ``_shared_input``):
        the value and the mean action as functions of parameters fetched once
        (``value_function``, ``mean_action_function`` of :mod:`crossroads.rl.neural_nets`: the same
        numbers, without a module call per layer) where the networks offer them, else their
        ``value_of_input`` and ``mean_action_of_input``."""
        value_of = getattr(self.value, "value_of_input", None)
        action_of = getattr(self.policy, "mean_action_of_input", None)
        if hasattr(self.value, "value_function"):
            value_of = self.value.value_function()
        if hasattr(self.policy, "mean_action_function"):
            action_of = self.policy.mean_action_function()
        return value_of, action_of

    def speed_mode(self, observation: Observation) -> SpeedMode:
        return speed_mode_from(_light_holds(observation), observation.front_vehicle_stopped_s)

    def decide_states(self, states: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
        """(τ*, action (2,), values (n,)) for the states of the n candidate paths (n, 108; 120 with
        the path preview)."""
        return self._decide_states(states, shared_rows=None)

    def _decide_states(self, states: np.ndarray, shared_rows: bool | None) -> tuple[int, np.ndarray, np.ndarray]:
        """:meth:`decide_states`; ``shared_rows``: whether the rows share x_ego and x_other (as
        :func:`build_states` makes them), None where that is to be checked."""
        # identical states get one value, the first's: a tie goes to the first path (below)
        firsts = first_identical(states).tolist()
        with torch.inference_mode():
            if self._shared_input:  # the networks' own numbers, bit for bit, one normalisation fewer
                x = torch.from_numpy(self._normalised(states, shared_rows))
                value_of, action_of = self._value_of_input, self._action_of_input
            else:
                x = torch.from_numpy(np.ascontiguousarray(states)).to(self._dtype)
                value_of, action_of = self.value, self.policy.mean_action
            computed = value_of(x).tolist()  # Python floats: the few values are picked and compared as such
            values = [computed[first] for first in firsts]
            best = _least_of(values)
            action = action_of(x[best:best + 1])[0].tolist()
        return best, np.array(action), np.array(values)

    def _normalised(self, states: np.ndarray, shared_rows: bool | None = None) -> np.ndarray:
        """``network_input`` of the candidates' states in the networks' dtype, in numpy with torch's
        sin and cos: the numbers the networks' own torch normalisation gives, at a fraction of its
        cost on a few states (:class:`crossroads.arrays.TorchTrigNumpyOps`); x_ego and x_other
        normalised once (``candidates_input``) where the rows share them (``shared_rows``, checked
        when None). Contiguous either way (one concatenate, or written into one array)."""
        data = np.ascontiguousarray(states, dtype=self._numpy_dtype)
        if shared_rows is None:
            shared_rows = rows_share_ego_and_others(data)
        normalise = candidates_input if shared_rows else network_input
        return normalise(data, self.policy.preview, self.policy.lead, xp=TorchTrigNumpyOps)

    def decide(self, observation: Observation) -> Decision:
        holds = _light_holds(observation)  # once a step: the mode and the shield's line both follow from it
        mode = speed_mode_from(holds, observation.front_vehicle_stopped_s)
        if self.shield:  # the shield's f_other turns each participant by its route's curvature
            others, kappa = observed_others(observation)
        else:
            others, kappa = select_others(observation.ego, observation.perceived.observations,
                                          observation.perceived.slot_kinds()), None
        states = build_states(observation.ego, others, self._candidates, mode, self.preview)
        best, action, values = self._decide_states(states, shared_rows=True)  # build_states' rows share them
        if kappa is None:
            return Decision(action, best, mode, values)
        line_m, crossing = self._shield_line(holds, observation, best)
        verdict = shield_action(observation.ego, others, kappa, action, line_m=line_m,
                                before_line=not observation.past_stop_line, braked_last_step=self._shield_braked,
                                exit_heading=float(self._candidates[best].heading[-1]))
        self._shield_braked = verdict.braking
        if verdict.braking and crossing is not None:
            if self._held_crossing is None or self._held_crossing[1] is not crossing:
                self._unclaimed_steps = 0
            self._held_crossing = (best, crossing)
        return Decision(verdict.action, best, mode, values, shield_braking=verdict.braking)

    def _shield_line(self, holds: bool, observation: Observation, path_index: int) -> tuple[float | None, CrossingSpan | None]:
        """The line the shield holds the ego short of, as the front bumper's distance [m]: the nearer
        of the stop line while the light holds the ego (:func:`_line_if`) and a crossing a
        pedestrian claims on path ``path_index`` (:meth:`_crosswalk`); with the crossing's span when
        the crossing is the nearer."""
        line = _line_if(holds, observation)
        crossing = self._crosswalk(observation, path_index)
        if crossing is None or (line is not None and line <= crossing[0]):
            return line, None
        return crossing

    def _crosswalk(self, observation: Observation, path_index: int) -> tuple[float, CrossingSpan] | None:
        """The claimed crossing on path ``path_index`` the shield holds the ego short of, and the
        bumper's distance to it [m]: the one it braked for while someone still claims it
        (:data:`HELD_CROSSING_RELEASE_STEPS`), else the nearest claimed one ahead while full braking
        can still stand short of it (:mod:`crossroads.idc.crosswalks`)."""
        if not observation.crossings:
            return None
        path = self._candidates[path_index]
        if path_index not in self._spans:
            self._spans[path_index] = crossing_spans(path.points, path.s, observation.crossings)
        if not self._spans[path_index]:
            return None
        seen = observation.perceived
        pedestrians = seen.observations[seen.kinds == "pedestrian"]
        if len(pedestrians) == 0 and self._held_crossing is None:
            return None  # nobody to claim a crossing: spare the projection
        ego = observation.ego
        front_s = path.project(float(ego[0]), float(ego[1])).s_m + EGO_LENGTH_M / 2.0
        speed = max(float(ego[2]), 0.0)
        held = self._held_crossing
        if held is not None and held[0] == path_index and observation.light.light == "green":
            span = held[1]
            self._unclaimed_steps = 0 if claims_ahead(span, front_s, pedestrians, speed) else self._unclaimed_steps + 1
            if self._unclaimed_steps < HELD_CROSSING_RELEASE_STEPS:
                return span.s_in_m - front_s, span
        self._held_crossing = None
        span = nearest_claimed(self._spans[path_index], front_s, pedestrians, speed)
        if span is None:
            return None
        gap = span.s_in_m - front_s
        # the braking distance only when needed: stepping f_ego costs ~40 µs
        if not can_stand_short_of(gap, braking_distance(speed, float(ego[7]))):
            return None
        return gap, span


# Values within this share of the least (relative, with an absolute floor for values near 0) are a
# tie, won by the first path: :func:`least_value_path`.
NEAR_TIE_RELATIVE = 1e-5
NEAR_TIE_ABSOLUTE = 1e-6


def least_value_path(values: np.ndarray) -> int:
    """τ*: the index of the first path whose value is within a near-tie of the least.

    Why not a plain argmin: candidate paths share their first metres, so their states, and their
    values, differ in the last digits for many steps, below the rounding that separates two runtimes
    of one network. The fine-tuned APG and its ONNX export, given the same observation (seed
    1538509758 of the nominal left turn, step 31), had 14.909682 / 14.909680 in torch and
    14.909687 / 14.909688 in onnxruntime, so each drove another path from there on. A tie of
    1e-5 (relative) is ~80 float32 roundings wide, and values that close say nothing of which
    path is better."""
    return _least_of(np.asarray(values, dtype=float).reshape(-1).tolist())


def _least_of(values: list[float]) -> int:
    """:func:`least_value_path` of values as Python floats (the decision's few, without a numpy call):
    the same float64 comparisons, and numpy's answers where a NaN or an infinity is involved (the
    first path: a NaN is the least of all to ``np.min`` and no value is within a NaN's tie)."""
    if any(v != v for v in values):
        return 0
    least = min(values)
    threshold = least + NEAR_TIE_RELATIVE * abs(least) + NEAR_TIE_ABSOLUTE
    return next((path for path, v in enumerate(values) if v <= threshold), 0)


def first_identical(states: np.ndarray) -> np.ndarray:
    """(n,) for each of the n states (n, width) the index of the first state equal to it, value for
    value (itself when none before is).

    Why: while the ego is on the metres its candidate paths share, their states are the same numbers
    and so, exactly, are their values; but a batched network rounds each row its own way (torch's
    float32 products gave row 1 of 3 identical states a value a few 1e-7 lower, onnxruntime all three
    the same), so the least value, and with it the path whose crossings and exit heading the shield
    checks, went to whichever row the rounding favoured. Measured on the first 50 seeds of the
    nominal left turn on c_three_lane (30 s): the shipped APG and its ONNX export, given the same
    observations, chose different paths at 2 to 14 steps of every episode (with the shield they once
    ended a seed of 50 differently, docs/guide/own-driver.md); with the tie to the first, at no
    step."""
    x = np.asarray(states)
    same = (x[:, None, :] == x[None, :, :]).all(axis=-1)
    np.fill_diagonal(same, True)  # a state with a NaN is still itself
    return same.argmax(axis=1)


def _light_holds(observation: Observation) -> bool:
    """:func:`crossroads.idc.lights.light_holds_at_line` for an observation."""
    return light_holds_at_line(
        past_stop_line=observation.past_stop_line,
        light=observation.light.light,
        distance_to_stop_line_m=observation.distance_to_stop_line_m,
        speed_mps=float(observation.ego[2]),
        yellow_remaining_s=observation.light.remaining_s,
    )


def _line_if(holds: bool, observation: Observation) -> float | None:
    """The shield's line: the front bumper's distance to the stop line [m] when the light ``holds``
    the ego there, else None. Why the shield needs it: the trained policies follow the stop profile
    loosely and crossed a red line on an empty road at 4.7 m/s (docs/tried/world.md, "Red lights")."""
    return observation.distance_to_stop_line_m if holds else None


BRAKING_STEPS_MAX = 400  # f_ego stops from 8.33 m/s in ~35 steps: the cap only guards absurd inputs


def braking_distance(speed: float, accel: float) -> float:
    """[m] :func:`crossroads.sim.ego.braking_distance_m` of one speed [m/s] (≥ 0) and acceleration
    [m/s²]: the same f_ego steps of full braking from a stand-in state on a straight road, stepped
    on Python floats (``ego_step_floats``, what ``ego_step`` does for one state) without its numpy
    calls per step (a tenth of the time; the shield asks every step someone claims a crossing)."""
    state: tuple[float, ...] = (0.0, 0.0, speed, 0.0, 0.0, 0.0, 0.0, min(max(accel, ACCEL_MIN), ACCEL_MAX))
    for _ in range(BRAKING_STEPS_MAX):
        if not state[2] > 0.0:
            break
        state = ego_step_floats(state, 0.0, -JERK_MAX)
    return state[0]
