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
ego's footprint stops where it is, and walks on as soon as either no longer holds (the ego drives
off, or it no longer faces the car). A moving ego gets no such courtesy: a pedestrian it drives
into is its collision.

Cyclists are left to SUMO on purpose: tried on the nominal right turn of ``e_irregular_oblique``,
a cyclist held short of an ego standing turned across the bike lane stood in the very place the
ego was waiting to clear, and the two waited on each other until the gridlock breaker removed the
cyclist: of the 4 runs that had ended in a cyclist riding into the standing ego at 12–30 s, 3
passed after 138–159 s and 1 timed out.

Pure geometry below; :class:`Courtesy` applies it to a session.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from crossroads.geometry import FloatArray
from crossroads.sim.sumo import SumoSession

EGO_STANDING_MPS = 0.5  # [m/s] below this the ego counts as standing
LOOKAHEAD_S = 1.0  # [s] how far ahead a pedestrian looks, at its speed
LOOKAHEAD_MIN_M = 1.0  # [m] ... and at least this far (one held still looks ahead too)
PEDESTRIAN_MARGIN_M = 0.35  # [m] half a pedestrian's 0.5 m body and 0.1 m to spare
_SAMPLES = np.linspace(0.0, 1.0, 8)  # points along the way ahead checked against the footprint
NEAR_M = 8.0  # [m] nobody farther from the ego's centre is checked


class Movers(NamedTuple):
    """The pedestrians of one step: SUMO ids and their centres, headings, speeds."""

    ids: np.ndarray
    x: FloatArray
    y: FloatArray
    heading: FloatArray
    speed: FloatArray


def moving_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                x: FloatArray, y: FloatArray, heading: FloatArray, reach: FloatArray,
                margin_m: float) -> np.ndarray:
    """Which of the movers at ``x``, ``y`` heading ``heading`` would, within ``reach`` [m] (at least
    :data:`LOOKAHEAD_MIN_M`), come into the ego's footprint widened by ``margin_m`` — and are not in
    it already (one already touching it is the judge's business, not this rule's)."""
    reach = np.maximum(np.asarray(reach, dtype=float), LOOKAHEAD_MIN_M)
    cos_e, sin_e = math.cos(ego_heading), math.sin(ego_heading)
    half_l, half_w = ego_length / 2.0 + margin_m, ego_width / 2.0 + margin_m
    # points along each one's way ahead, in the ego's frame: (n, samples)
    px = np.asarray(x)[:, None] + np.cos(heading)[:, None] * reach[:, None] * _SAMPLES
    py = np.asarray(y)[:, None] + np.sin(heading)[:, None] * reach[:, None] * _SAMPLES
    dx, dy = px - ego_x, py - ego_y
    along = dx * cos_e + dy * sin_e
    across = -dx * sin_e + dy * cos_e
    inside = (np.abs(along) <= half_l) & (np.abs(across) <= half_w)
    return inside[:, 1:].any(axis=1) & ~inside[:, 0]


def walking_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                 x: FloatArray, y: FloatArray, heading: FloatArray, speed: FloatArray) -> np.ndarray:
    """:func:`moving_into` for pedestrians: :data:`LOOKAHEAD_S` at their speed."""
    return moving_into(ego_x, ego_y, ego_heading, ego_length, ego_width, x, y, heading,
                       np.asarray(speed, dtype=float) * LOOKAHEAD_S, PEDESTRIAN_MARGIN_M)


class Courtesy:
    """Holds the pedestrians that would walk into the standing ego (see the module's rule) and lets
    them go again; ``enabled`` False turns the rule off."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        self.held_pedestrians: set[str] = set()

    def may_act(self, ego_speed: float) -> bool:
        """Whether :meth:`update` can change anything: the ego stands, or someone is held."""
        return self.enabled and (ego_speed < EGO_STANDING_MPS or bool(self.held_pedestrians))

    def update(self, session: SumoSession, pedestrians: Movers,
               ego: tuple[float, float, float, float, float, float]) -> None:
        """``ego``: its (x, y, heading, speed, length, width). Holds and releases through
        ``session``."""
        if not self.enabled:
            return
        standing = ego[3] < EGO_STANDING_MPS
        now = _who(pedestrians, ego, walking_into) if standing else set()
        self.held_pedestrians = _apply(now, self.held_pedestrians, pedestrians.ids,
                                       session.hold_person, session.release_person)


def _who(movers: Movers, ego: tuple[float, float, float, float, float, float],
         test: Callable[..., np.ndarray]) -> set[str]:
    ego_x, ego_y, ego_heading, _, length, width = ego
    if not len(movers.ids):
        return set()
    near = (np.hypot(np.asarray(movers.x) - ego_x, np.asarray(movers.y) - ego_y) < NEAR_M).nonzero()[0]
    if not len(near):
        return set()
    into = test(ego_x, ego_y, ego_heading, length, width, np.asarray(movers.x)[near], np.asarray(movers.y)[near],
                np.asarray(movers.heading)[near], np.asarray(movers.speed)[near])
    return {str(movers.ids[r]) for r in near[into]}


def _apply(now: set[str], held: set[str], present_ids: np.ndarray,
           hold: Callable[[str], None], release: Callable[[str], None]) -> set[str]:
    """Hold the new ones, release those no longer to hold that are still there; the new held set."""
    for pid in now - held:
        hold(pid)
    gone = held - now
    if gone:
        present = {str(i) for i in present_ids}
        for pid in gone & present:  # one that has left the simulation needs no release
            release(pid)
    return now
