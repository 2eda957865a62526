"""A minimal driver as a Python plugin: ``--policy py:cautious_driver:CautiousDriver``.

Run it (from the repository root, the directory of this file on PYTHONPATH so every process that
runs episodes can import it)::

    PYTHONPATH=examples/plugin_driver crossroads run scenarios/nominal/c_three_lane-left.yaml \\
        --policy py:cautious_driver:CautiousDriver

What it does, in ~50 lines: it follows the first candidate path (pure pursuit for the steering),
holds a modest speed, stops short of the stop line while the light is not green and it has not
crossed yet, and brakes when anyone it perceives is within a few metres ahead of its bumper. It is
an example of the protocol (crossroads.idc.controller.Controller), not a good driver: it never
negotiates a gap.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from crossroads.idc.controller import Decision
from crossroads.planning import CandidatePath
from crossroads.sim.observation import Observation

CRUISE_MPS = 6.0  # [m/s] the speed it holds
LOOKAHEAD_M = 6.0  # [m] pure-pursuit look-ahead
WHEELBASE_M = 2.65  # [m]
STOP_SHORT_M = 1.0  # [m] stops its bumper this far before the stop line
CLEARANCE_M = 8.0  # [m] someone this close ahead (within 2 m of its axis): brake


class CautiousDriver:
    """Implements the controller protocol: ``name``, ``reset(candidates)``, ``decide(observation)``."""

    name = "cautious"

    def __init__(self) -> None:
        self.path: CandidatePath | None = None

    def reset(self, candidates: Sequence[CandidatePath]) -> None:
        self.path = candidates[0]  # one path for the whole episode

    def decide(self, observation: Observation) -> Decision:
        assert self.path is not None, "reset() comes first"
        x, y, v, _, heading, _, steer, accel = observation.ego.tolist()
        # steering: pure pursuit on the point LOOKAHEAD_M further along the path
        s_here = self.path.project(x, y).s_m
        k = min(int(np.searchsorted(self.path.s, s_here + LOOKAHEAD_M)), len(self.path.s) - 1)
        tx, ty = self.path.points[k]
        alpha = math.atan2(ty - y, tx - x) - heading
        target_steer = math.atan2(2.0 * WHEELBASE_M * math.sin(alpha), LOOKAHEAD_M)
        # speed: cruise, or stop at the line before a light that is not green, or for someone ahead
        target_v = CRUISE_MPS
        gap = observation.distance_to_stop_line_m - STOP_SHORT_M
        if not observation.past_stop_line and observation.light.light != "green":
            target_v = min(target_v, math.sqrt(max(0.0, 2.0 * 2.0 * gap)))  # 2 m/s² to a stand
        seen = observation.perceived.observations
        if len(seen):
            dx, dy = seen[:, 0] - x, seen[:, 1] - y
            ahead = dx * math.cos(heading) + dy * math.sin(heading)
            aside = np.abs(-dx * math.sin(heading) + dy * math.cos(heading))
            if np.any((ahead > 0.0) & (ahead < CLEARANCE_M) & (aside < 2.0)):
                target_v = 0.0
        target_accel = float(np.clip(0.8 * (target_v - v), -3.0, 1.5))
        # the actions are rates: steering rate [rad/s] and jerk [m/s³], 0.1 s per step
        action = np.array([(target_steer - steer) / 0.1, (target_accel - accel) / 0.1])
        mode = "pass" if target_v > 0.0 else "stop"
        return Decision(np.clip(action, [-0.4, -4.5], [0.4, 4.5]), 0, mode)
