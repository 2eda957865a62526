"""What the Gymnasium environment observes: the IDC state, field by field, and its spaces.

The observation is the state s of :mod:`crossroads.idc.state` for the path the environment tracks,
as float32, raw (world frame, SI units; :func:`crossroads.idc.state.network_input` makes it
ego-relative and scaled the way the shipped networks read it):

=========  ================================  =====================================================
index      field                             meaning
=========  ================================  =====================================================
0, 1       ego p_x, p_y [m]                  centre of the ego, network frame
2, 3       ego v_x, v_y [m/s]                longitudinal and lateral speed (vehicle frame)
4          ego φ [rad]                       heading, counter-clockwise from +x
5          ego ω [rad/s]                     yaw rate
6          ego δ [rad]                       front wheel angle (|δ| ≤ 0.4)
7          ego a [m/s²]                      acceleration (−3 … 1.5)
8, 9       Δx, Δy [m]                        position error to the path's nearest point, in the
                                             path's frame (along, left)
10         Δv [m/s]                          v_x − the speed profile there (pass or stop mode)
11         Δφ [rad]                          heading error, wrapped to ±π
12 … 59    8 vehicles × [p_x, p_y, v, φ, L, W]   closest first; [m, m, m/s, rad, m, m], noisy
60 … 83    4 cyclists × the same
84 … 107   4 pedestrians × the same           (empty slots: a virtual participant 100 m behind the
                                             ego, speed 0; see ``idc.state.pad_participant``)
108 … 119  path preview (``preview=True``)   lateral offsets [m], relative headings [rad] and
                                             v_ref [m/s] of the path 5, 10, 15, 20 m ahead
=========  ================================  =====================================================

The speed mode (pass/stop: which profile Δv refers to) is the paper's traffic-light logic, as the
IDC decision uses (``idc.lights.choose_speed_mode``). The tracked path: the candidate nearest the
ego (least √(Δx² + Δy²); ties: the first) by default, or one fixed candidate. With
``observation="dict"`` the observation also holds the state of every candidate path, in the
environment's candidate order, and the index of the tracked one. The box observation's state is
built alone (``idc.state.tracked_state``: the same numbers as the tracked row of every candidate's).
"""

from __future__ import annotations

from typing import Any, Literal, NamedTuple

import numpy as np
from gymnasium import spaces

from crossroads.constants import JERK_MAX, STATE_DIM, STEER_RATE_MAX
from crossroads.idc.controller import SpeedMode
from crossroads.idc.lights import choose_speed_mode
from crossroads.idc.state import DX, DY, PREVIEW_STATE_DIM, build_states, select_others, tracked_state
from crossroads.sim.observation import Observation

ObservationKind = Literal["box", "dict"]
PathChoice = Literal["nearest"] | int
ACTION_LOW = np.array([-STEER_RATE_MAX, -JERK_MAX], dtype=np.float32)  # [Δδ rad/s, Δa m/s³]
ACTION_HIGH = np.array([STEER_RATE_MAX, JERK_MAX], dtype=np.float32)


def state_width(preview: bool) -> int:
    """Values per state: 108, or 120 with the path preview."""
    return PREVIEW_STATE_DIM if preview else STATE_DIM


def action_space() -> spaces.Box:
    """[Δδ, Δa] in the paper's ranges: ±0.4 rad/s, ±4.5 m/s³."""
    return spaces.Box(ACTION_LOW, ACTION_HIGH, dtype=np.float32)


def observation_space(kind: ObservationKind, width: int, n_candidates: int) -> spaces.Space[Any]:
    """A Box of one state, or a Dict with every candidate's state and the tracked path's index."""
    state = spaces.Box(-np.inf, np.inf, shape=(width,), dtype=np.float32)
    if kind == "box":
        return state
    return spaces.Dict({
        "state": state,
        "candidates": spaces.Box(-np.inf, np.inf, shape=(n_candidates, width), dtype=np.float32),
        "path": spaces.Discrete(n_candidates),
    })


class IdcView(NamedTuple):
    """The IDC's view of one world observation: the tracked path's state and, when asked for,
    every candidate's."""

    state: np.ndarray  # (width,) float64, the tracked candidate's
    path: int  # the tracked candidate
    speed_mode: SpeedMode
    states: np.ndarray | None = None  # (n_candidates, width) float64; None: not built

    def observation(self, kind: ObservationKind) -> Any:
        state = self.state.astype(np.float32)
        if kind == "box":
            return state
        if self.states is None:
            raise ValueError("the dict observation needs every candidate's state: idc_view(..., every=True)")
        return {"state": state, "candidates": self.states.astype(np.float32), "path": self.path}


def idc_view(obs: Observation, preview: bool, path: PathChoice, every: bool = True) -> IdcView:
    """The states of ``obs`` (as :class:`~crossroads.idc.decision.IdcController` builds them: the
    perceived participants, the light's speed mode) and the path to track.

    With ``every=False`` only the tracked path's state is built (the same numbers:
    :func:`~crossroads.idc.state.tracked_state`), which is all the box observation needs."""
    mode = choose_speed_mode(
        front_vehicle_stopped_s=obs.front_vehicle_stopped_s, past_stop_line=obs.past_stop_line,
        light=obs.light.light, distance_to_stop_line_m=obs.distance_to_stop_line_m,
        speed_mps=float(obs.ego[2]), yellow_remaining_s=obs.light.remaining_s)
    seen = obs.perceived
    if not every:
        index, state = tracked_state(obs.ego, seen.observations, seen.slot_kinds(), obs.candidates, mode,
                                     None if path == "nearest" else int(path), preview)
        return IdcView(state, index, mode)
    others = select_others(obs.ego, seen.observations, seen.slot_kinds())
    states = build_states(obs.ego, others, obs.candidates, mode, preview)
    index = int(np.hypot(states[:, DX], states[:, DY]).argmin()) if path == "nearest" else int(path)
    return IdcView(states[index], index, mode, states)
