"""Pedestrians do not walk into a standing ego, the world's rule.

SUMO's pedestrians walk their crossings and walking areas whatever stands there: a car standing
with its rear over a crossing (a left-turner at its waiting point inside the junction, a queue
reaching back over the crosswalk) is walked into when the walk begins, and the judge counts that
as the ego's collision. Measured with SUMO's own driver on the nominal left turn of
``e_irregular_oblique`` (30 runs, base seed 20261206): 17 of its 20 collisions were pedestrians
walking into the ego standing at its waiting point. No pedestrian does that; they stop, or step
round the car.

The rule: while the ego stands (below :data:`EGO_STANDING_MPS`), a pedestrian whose next
:data:`LOOKAHEAD_S` of walking (at least :data:`LOOKAHEAD_MIN_M`) would bring its body into the
ego's footprint stops where it is; it walks on as soon as either no longer holds (the ego drives
off, or it no longer faces the car). A moving ego gets no such courtesy: a pedestrian it drives
into is its collision. Pure geometry below; :class:`PedestrianCourtesy` applies it to a session.
"""

from __future__ import annotations

import math

import numpy as np

from crossroads.geometry import FloatArray
from crossroads.sim.sumo import SumoSession

EGO_STANDING_MPS = 0.5  # [m/s] below this the ego counts as standing
LOOKAHEAD_S = 1.0  # [s] how far ahead a pedestrian looks, at its walking speed
LOOKAHEAD_MIN_M = 1.0  # [m] ... and at least this far (a pedestrian held still looks ahead too)
BODY_MARGIN_M = 0.35  # [m] half a pedestrian's 0.5 m body and 0.1 m to spare
_SAMPLES = np.linspace(0.0, 1.0, 6)  # points along the look-ahead checked against the footprint
NEAR_M = 8.0  # [m] pedestrians farther from the ego's centre are not checked


def walking_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                 x: FloatArray, y: FloatArray, heading: FloatArray, speed: FloatArray) -> np.ndarray:
    """Which pedestrians (arrays ``x``, ``y``, ``heading``, ``speed``) would walk into the ego's
    footprint, widened by :data:`BODY_MARGIN_M`, within their look-ahead — and do not overlap it
    already (one already touching it is the judge's business, not this rule's)."""
    reach = np.maximum(np.asarray(speed) * LOOKAHEAD_S, LOOKAHEAD_MIN_M)
    cos_e, sin_e = math.cos(ego_heading), math.sin(ego_heading)
    half_l, half_w = ego_length / 2.0 + BODY_MARGIN_M, ego_width / 2.0 + BODY_MARGIN_M
    # points along each pedestrian's look-ahead, in the ego's frame: (n, samples)
    px = np.asarray(x)[:, None] + np.cos(heading)[:, None] * reach[:, None] * _SAMPLES
    py = np.asarray(y)[:, None] + np.sin(heading)[:, None] * reach[:, None] * _SAMPLES
    dx, dy = px - ego_x, py - ego_y
    along = dx * cos_e + dy * sin_e
    across = -dx * sin_e + dy * cos_e
    inside = (np.abs(along) <= half_l) & (np.abs(across) <= half_w)
    return inside[:, 1:].any(axis=1) & ~inside[:, 0]


class PedestrianCourtesy:
    """Holds the pedestrians that would walk into the standing ego (see the module's rule) and
    lets them go again; ``enabled`` False turns the rule off."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        self.held: set[str] = set()

    def may_act(self, ego_speed: float) -> bool:
        """Whether :meth:`update` can change anything: the ego stands, or someone is held."""
        return self.enabled and (ego_speed < EGO_STANDING_MPS or bool(self.held))

    def update(self, session: SumoSession, ids: np.ndarray, x: FloatArray, y: FloatArray, heading: FloatArray,
               speed: FloatArray, ego: tuple[float, float, float, float, float, float]) -> None:
        """``ids``/``x``/``y``/``heading``/``speed``: this step's pedestrians; ``ego``: its
        (x, y, heading, speed, length, width). Holds and releases through ``session``'s
        ``hold_person``/``release_person``."""
        if not self.enabled:
            return
        ego_x, ego_y, ego_heading, ego_speed, length, width = ego
        now: set[str] = set()
        if ego_speed < EGO_STANDING_MPS and len(ids):
            near = np.hypot(np.asarray(x) - ego_x, np.asarray(y) - ego_y) < NEAR_M
            if near.any():
                rows = near.nonzero()[0]
                into = walking_into(ego_x, ego_y, ego_heading, length, width,
                                    np.asarray(x)[rows], np.asarray(y)[rows],
                                    np.asarray(heading)[rows], np.asarray(speed)[rows])
                now = {str(ids[r]) for r in rows[into]}
        present = {str(i) for i in ids}
        for pid in now - self.held:
            session.hold_person(pid)
        for pid in self.held - now:
            if pid in present:  # one that has left the simulation needs no release
                session.release_person(pid)
        self.held = now
