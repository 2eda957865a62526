"""SUMO's driver, when it drives the ego, brakes for a pedestrian or cyclist in its way ahead.

SUMO's driver yields to pedestrians only at a crossing's link: once its front has passed that
link it no longer sees the crossing's walkers, and a left-turner waiting inside the junction
drives off into a pedestrian walking in front of its bumper. Measured (30 runs, base seed
20261206): all 7 pedestrian collisions of SUMO's driver on the 18 nominal and 6 paper scenarios
were on the nominal left turn of ``e_irregular_oblique``, where its waiting point lies over the
crossing of its own approach; in one looked at (seed 196642405, 77.6 s) it started into a
pedestrian 0.6 m ahead of its bumper. The ``sumo`` policy is the baseline of what the world lets
through, a driver with SUMO's full knowledge, and no driver does that.

The rule: every step, a pedestrian or cyclist whose body is, or within :data:`PREDICTION_S` at its
speed will be, in the corridor ahead of the ego's front bumper (as wide as the ego and the
other's body, plus :data:`LATERAL_MARGIN_M` a side; as long as the ego's braking distance at
:data:`COMFORT_DECEL_MPS2` plus :data:`BUFFER_M`) makes SUMO's driver stop (a commanded speed of 0,
which SUMO reaches at the driver's own deceleration); with no one there, SUMO's driver has the ego
again. A pedestrian or cyclist the world holds for the standing ego (``sim/courtesy.py``) is not
looked at: it waits for the ego to go, and the two would wait on each other — tried: counting them,
SUMO's driver stood through whole cycles in front of a held pedestrian, and the nominal left turn
of ``e_irregular_oblique`` passed 13 of 30 with 12 timeouts (without this rule 14, with 6 timeouts
and 10 collisions; with it as it is, three measurements: 14–15 passes, 4–5 collisions, 10–11
timeouts). The ego's own controller policies never get
this: it is part of the ``sumo`` baseline, not of the world. ``SumoDriver.look_ahead`` False turns
it off.

Pure geometry below; :class:`LookAhead` applies it to a session.
"""

from __future__ import annotations

import math

import numpy as np

from crossroads.geometry import FloatArray
from crossroads.sim.sumo import SumoSession

COMFORT_DECEL_MPS2 = 3.0  # [m/s²] the braking the corridor's length allows for
BUFFER_M = 2.0  # [m] the corridor's length beyond the braking distance
LATERAL_MARGIN_M = 0.3  # [m] on each side of the ego's and the other's half widths
PREDICTION_S = 1.0  # [s] how far ahead the others' positions are looked at, at their speed
_TIMES = np.array([0.0, 0.5, 1.0]) * PREDICTION_S  # the moments checked
NEAR_M = 30.0  # [m] nobody farther from the ego's centre is checked


def corridor_length(speed_mps: float) -> float:
    """[m] how far ahead of its front bumper the ego looks at ``speed_mps``."""
    v = max(speed_mps, 0.0)
    return v * v / (2.0 * COMFORT_DECEL_MPS2) + BUFFER_M


def in_the_way(ego_x: float, ego_y: float, ego_heading: float, ego_speed: float, length: float,
               width: float, xs: FloatArray, ys: FloatArray, headings: FloatArray, speeds: FloatArray,
               radii: FloatArray) -> np.ndarray:
    """(n,) bool: whose body (a disc of its radius: half the larger of its length and width) is,
    now or within :data:`PREDICTION_S` at its speed and heading, in the corridor ahead of the
    ego's front bumper (module docstring). Headings [rad] counter-clockwise from +x."""
    c, s = math.cos(ego_heading), math.sin(ego_heading)
    front_x, front_y = ego_x + 0.5 * length * c, ego_y + 0.5 * length * s
    reach = corridor_length(ego_speed)
    # positions at each moment: (n, len(_TIMES))
    px = (xs - front_x)[:, None] + (speeds * np.cos(headings))[:, None] * _TIMES
    py = (ys - front_y)[:, None] + (speeds * np.sin(headings))[:, None] * _TIMES
    ahead = px * c + py * s
    lateral = py * c - px * s
    body = radii[:, None]
    inside = ((ahead > -body) & (ahead < reach + body)
              & (np.abs(lateral) < 0.5 * width + LATERAL_MARGIN_M + body))
    return inside.any(axis=1)


class LookAhead:
    """Applies :func:`in_the_way` to SUMO's driver of the ego, step by step."""

    def __init__(self, ego_id: str, enabled: bool = True) -> None:
        self.ego_id = ego_id
        self.enabled = enabled
        self.braking = False  # whether the ego's speed is commanded to 0 now

    def update(self, session: SumoSession, ego: tuple[float, float, float, float, float, float],
               xs: FloatArray, ys: FloatArray, headings: FloatArray, speeds: FloatArray,
               radii: FloatArray) -> bool:
        """``ego``: its (x, y, heading, speed, length, width); the pedestrians' and cyclists'
        centres, headings [rad], speeds and radii (:func:`in_the_way`). Commands the stop or hands
        the ego back to SUMO's driver; whether it is braking now."""
        if not self.enabled:
            return False
        x, y, heading, speed, length, width = ego
        near = (np.hypot(xs - x, ys - y) < NEAR_M).nonzero()[0]
        blocked = bool(len(near)) and bool(in_the_way(
            x, y, heading, speed, length, width, xs[near], ys[near], headings[near], speeds[near],
            radii[near]).any())
        if blocked != self.braking:
            session.set_speed(self.ego_id, 0.0 if blocked else -1.0)
            self.braking = blocked
        return blocked
