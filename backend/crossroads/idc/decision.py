"""Online IDC decision (SPEC §4, §7; paper eq. "apply value policy").

Every step: the traffic-light logic picks the speed mode; the state of every candidate path is
built in that mode and the batch goes through the value network; the path of least value is
τ* = argmin_τ v_w(s(τ)); the driving policy's mean action for s(τ*) is the command.

The networks are plain torch modules (anything with the shapes of :mod:`crossroads.rl.networks`),
so this module does not depend on the training code; :meth:`IdcController.from_checkpoint` loads a
trained run's networks through :mod:`crossroads.rl.checkpoint` when asked to.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from torch import nn

from crossroads.constants import DT_S, EGO_LENGTH_M
from crossroads.idc.controller import Decision, SpeedMode
from crossroads.idc.conflicts import COMMIT_SLACK_M, CONFLICT_HORIZON_S, MOVING_MPS, crossing, nearest_conflict_m
from crossroads.idc.crosswalks import CrossingSpan, can_stand_short_of, crossing_spans, nearest_claimed_m
from crossroads.idc.lights import light_holds_at_line, speed_mode_from
from crossroads.idc.observed import observed_others
from crossroads.idc.shield import predicted_others, shield_action
from crossroads.idc.state import build_states, select_others
from crossroads.planning import CandidatePath
from crossroads.sim.ego import braking_distance_m
from crossroads.sim.lanes_ahead import CentreLine, centre_line, drive_along, lanes_ahead
from crossroads.sim.world import Observation, participant_curvatures

CONFLICT_STEPS = round(CONFLICT_HORIZON_S / DT_S)  # the crossing traffic's prediction (idc.conflicts)


class IdcController:
    """Value network picks the path, driving policy tracks it (mean action); with ``shield``, the
    safety shield (:mod:`crossroads.idc.shield`) checks that action (off by default: not the paper's)."""

    def __init__(self, policy: nn.Module, value: nn.Module, name: str = "idc", shield: bool = False) -> None:
        self.policy = policy.eval()
        self.value = value.eval()
        self.name = name
        self._dtype = next(value.parameters()).dtype
        self._candidates: tuple[CandidatePath, ...] = ()
        self.shield = shield
        self._shield_braked = False  # the shield's verdict last step: it releases with a margin (idc.shield)
        self._spans: dict[int, tuple[CrossingSpan, ...]] = {}  # per candidate: its crossings (idc.crosswalks)
        self._lines: dict[tuple[str, ...], CentreLine | None] = {}  # lanes ahead joined (predicted_crossing_traffic)
        # networks built with the path preview read 120-value states (crossroads.idc.state)
        self.preview = bool(getattr(policy, "preview", False))

    @classmethod
    def from_checkpoint(cls, path: str | Path, shield: bool = False) -> IdcController:
        from crossroads.rl.checkpoint import load_networks

        networks, _ = load_networks(Path(path))
        name = Path(path).stem + ("+shield" if shield else "")
        return cls(networks.policy, networks.value, name=name, shield=shield)

    def reset(self, candidates: Sequence[CandidatePath]) -> None:
        self._candidates = tuple(candidates)
        self._shield_braked = False
        self._spans = {}
        self._lines = {}

    def speed_mode(self, observation: Observation) -> SpeedMode:
        return speed_mode_from(_light_holds(observation), observation.front_vehicle_stopped_s)

    def decide_states(self, states: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
        """(τ*, action (2,), values (n,)) for the states of the n candidate paths (n, 108; 120 with
        the path preview)."""
        with torch.inference_mode():
            batch = torch.from_numpy(np.ascontiguousarray(states)).to(self._dtype)
            values = self.value(batch)
            best = int(torch.argmin(values))
            action = self.policy.mean_action(batch[best:best + 1])[0]
        return best, action.double().numpy(), values.double().numpy()

    def decide(self, observation: Observation) -> Decision:
        holds = _light_holds(observation)  # once a step: the mode and the shield's line both follow from it
        mode = speed_mode_from(holds, observation.front_vehicle_stopped_s)
        if self.shield:  # the shield's f_other turns each participant by its route's curvature
            others, kappa = observed_others(observation)
        else:
            others, kappa = select_others(observation.ego, observation.perceived.observations,
                                          observation.perceived.kinds), None
        states = build_states(observation.ego, others, self._candidates, mode, self.preview)
        best, action, values = self.decide_states(states)
        if kappa is None:
            return Decision(action, best, mode, values)
        verdict = shield_action(observation.ego, others, kappa, action, line_m=self._shield_line(holds, observation, best),
                                before_line=not observation.past_stop_line, braked_last_step=self._shield_braked,
                                exit_heading=float(self._candidates[best].heading[-1]))
        self._shield_braked = verdict.braking
        return Decision(verdict.action, best, mode, values, shield_braking=verdict.braking)

    def _shield_line(self, holds: bool, observation: Observation, path_index: int) -> float | None:
        """The line the shield holds the ego short of, as the front bumper's distance [m]: the
        nearest of the stop line while the light holds the ego (:func:`_line_if`), a crossing a
        pedestrian claims on path ``path_index`` (:mod:`crossroads.idc.crosswalks`) and the line
        short of crossing traffic (:mod:`crossroads.idc.conflicts`) — the last two only while full
        braking can still stand short of them."""
        lines = [line] if (line := _line_if(holds, observation)) is not None else []
        path = self._candidates[path_index]
        ego = observation.ego
        front_s = path.project(float(ego[0]), float(ego[1])).s_m + EGO_LENGTH_M / 2.0
        speed = max(float(ego[2]), 0.0)
        # (line, how far past it full braking may still end before the line is given up)
        ahead = [(gap, slack) for gap, slack in ((self._claimed_crossing_m(observation, path_index, front_s, speed), 0.0),
                                                 (self._yield_at_stop_line_m(observation, speed), COMMIT_SLACK_M))
                 if gap is not None]
        if ahead:
            stopping = float(braking_distance_m(speed, float(ego[7])))  # only when needed: stepping f_ego costs ~0.2 ms
            lines += [gap for gap, slack in ahead if can_stand_short_of(gap + slack, stopping)]
        return min(lines) if lines else None

    def _claimed_crossing_m(self, observation: Observation, path_index: int, front_s: float, speed: float) -> float | None:
        """The bumper's distance [m] to the nearest crossing on the path a pedestrian claims, or None."""
        if not observation.crossings:
            return None
        if path_index not in self._spans:
            path = self._candidates[path_index]
            self._spans[path_index] = crossing_spans(path.points, path.s, observation.crossings)
        seen = observation.perceived
        pedestrians = seen.observations[seen.kinds == "pedestrian"]
        if not self._spans[path_index] or len(pedestrians) == 0:
            return None
        return nearest_claimed_m(self._spans[path_index], front_s, pedestrians, speed)

    def _yield_at_stop_line_m(self, observation: Observation, speed: float) -> float | None:
        """The bumper's distance [m] to the stop line while the ego is short of it and crossing
        traffic claims a stretch of a candidate path ahead (:meth:`_crossing_traffic_m`), else None:
        the ego accepts a gap at the stop line, and once past it is committed. Why not yield inside
        the junction, short of the claimed stretch itself: SUMO's vehicles drive into an ego standing
        there (left-turners from the lane beside it, the cross street's traffic once the light has
        turned); yielding there, 200 nominal left turns (150 s) passed 116 instead of 132, with 50
        collisions instead of 35."""
        if observation.past_stop_line or self._crossing_traffic_m(observation, speed) is None:
            return None
        return observation.distance_to_stop_line_m

    def _crossing_traffic_m(self, observation: Observation, speed: float) -> float | None:
        """The bumper's distance [m] to the line short of crossing traffic
        (:func:`crossroads.idc.conflicts.nearest_conflict_m`), the nearest over every candidate
        path, or None. Why every path: the value network may switch paths on the way; on the nominal
        left turn (150 s, seed 896230294) a switch to the tighter turn inside the junction moved the
        line from 9 m ahead, where the ego could stop, to 3 m, where it could not."""
        seen = observation.perceived
        rows = np.flatnonzero(seen.kinds != "pedestrian")
        rows = rows[seen.observations[rows, 2] >= MOVING_MPS]
        if len(rows) == 0:
            return None
        across = np.array([crossing(seen.observations[rows], path.points, path.heading) for path in self._candidates])
        rows, across = rows[across.any(axis=0)], across[:, across.any(axis=0)]  # (paths, k): who crosses which
        if len(rows) == 0:
            return None
        predicted = predicted_crossing_traffic(observation, seen.observations[rows], seen.rows[rows], CONFLICT_STEPS, self._lines)
        ego = observation.ego
        gaps = []
        for path, crosses in zip(self._candidates, across, strict=True):
            if crosses.any():
                front_s = path.project(float(ego[0]), float(ego[1])).s_m + EGO_LENGTH_M / 2.0
                gap = nearest_conflict_m(path.points, path.heading, path.s, front_s, speed, predicted[:, crosses])
                if gap is not None:
                    gaps.append(gap)
        return min(gaps) if gaps else None


def predicted_crossing_traffic(observation: Observation, others: np.ndarray, rows: np.ndarray, steps: int,
                               lines: dict[tuple[str, ...], CentreLine | None]) -> np.ndarray:
    """(steps, k, 6): the perceived participants ``others`` (k, 6) (snapshot ``rows`` (k,)) keeping
    their speed along their lanes ahead (:mod:`crossroads.sim.lanes_ahead`), or, where the map does
    not say, turning by their lane's curvature (f_other). ``lines`` caches the joined centre lines
    by their lanes (they are static)."""
    snap = observation.participants
    out = np.repeat(np.asarray(others, np.float64)[None], steps, axis=0)
    unknown = []
    for k, row in enumerate(rows):
        lanes = lanes_ahead(observation.lane_successors, str(snap.lane_id[row]), snap.route[row])
        if lanes not in lines:
            lines[lanes] = centre_line(observation.lane_shapes, lanes)
        line = lines[lanes]
        if line is None:
            unknown.append(k)
            continue
        out[:, k, :2], out[:, k, 3] = drive_along(line, float(others[k, 0]), float(others[k, 1]), float(others[k, 2]), steps)
    if unknown:
        kappa = participant_curvatures(observation.lane_shapes, snap, rows[unknown])
        out[:, unknown] = predicted_others(others[unknown], kappa, steps)[0]
    return out


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
    loosely and crossed a red line on an empty road at 4.7 m/s (docs/measurements/red-lights.md)."""
    return observation.distance_to_stop_line_m if holds else None
