"""Drivers let those caught inside the junction out before they enter on green, the world's rule.

A vehicle still inside the junction when the light of its movement is no longer green clears it
(``sim/clearing.py``; SUMO's driver of the ego does the same, ``SumoDriver.clear_junction``). SUMO
does not have the cross street wait for it: a car whose link turns green enters, and SUMO's
driver of the one clearing yields to every vehicle already on an internal lane across its way.
With three lanes of cross traffic starting on green, a left-turner caught at its waiting point
found no gap for a whole green: on ``e_irregular_oblique``'s nominal left turn SUMO's driver timed
out in 59 of 200 runs that way (docs/tried/world.md). Drivers do not enter across someone
clearing the junction; they let them out first.

The rule: while a vehicle caught inside the junction (the world's, or the ego, whoever drives
it) has been caught for at most :data:`LET_OUT_FOR_S`, a driver (car or bicycle; not the ego,
not an abnormal one, which the scenario makes reckless on purpose) approaching the junction on
green whose way through it comes within both half widths plus :data:`WAY_MARGIN_M` of the caught
one's remaining way waits before its stop line — as long as it can still stop there at
:data:`COMFORT_DECEL_MPS2`; one that cannot is on its way in. It goes as soon as no one it waits
for is caught inside across its way, after :data:`LET_OUT_FOR_S` at the latest (a caught vehicle
standing in a knot is the knot rule's business, not a reason to stop a green). The ego, caught and
moving (faster than :data:`MOVING_MPS`), is let out however long it has been caught, and a driver
already inside the junction on its green brakes for it too, if it can still stop short of where
their ways meet: when the bound let the cross street go just as the ego, standing there 20 s
behind the oncoming traffic clearing the junction, set off, the cross street's first car drove
into its side (``e_irregular_oblique``'s left turn, both of its collisions at 200 runs). The
world's own caught vehicles keep the bound (the knot rule of ``sim/clearing.py`` gets them out;
letting them out too while they move took the vehicles crossing ``e_irregular_oblique`` from 76 to
66 % of their demand). ``let_out``: ``false`` in a scenario's world turns it off.

Pure geometry first; :class:`LettingOut` applies it to a session, checked every
:data:`CHECK_EVERY_S` of simulated time.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from crossroads.geometry import FloatArray, arc_lengths, distances_to_polyline, resample
from crossroads.sim.cadence import Every
from crossroads.sim.clearing import CHECK_EVERY_S, WAY_MARGIN_M, remaining_way
from crossroads.sim.sumo import GREEN_LINK_STATES, SumoSession

LET_OUT_FOR_S = 20.0  # [s] how long after it was caught a standing vehicle inside the junction is let out
MOVING_MPS = 0.5  # [m/s] a caught ego faster than this is let out however long it has been caught
HOLDER = "letting_out"  # this rule's name among those holding a vehicle (SumoSession.hold_vehicle)
COMFORT_DECEL_MPS2 = 3.0  # [m/s²] a driver waits only if it can stop before its line braking at this
APPROACH_M = 60.0  # [m] drivers farther from their stop line are not looked at (14 m/s stops in 33 m)
SAMPLE_M = 0.5  # [m] spacing of the points along a way checked against the other


def ways_meet(way: FloatArray, other: FloatArray, reach_m: float) -> bool:
    """Whether polylines ``way`` and ``other`` (n, 2) [m] come within ``reach_m`` of each other."""
    if len(way) == 0 or len(other) == 0:
        return False
    return bool((distances_to_polyline(resample(way, SAMPLE_M), other) < reach_m).any()
                or (distances_to_polyline(resample(other, SAMPLE_M), way) < reach_m).any())


def distance_to_meeting(way: FloatArray, other: FloatArray, reach_m: float) -> float | None:
    """[m] along polyline ``way`` (n, 2) to its first point within ``reach_m`` of polyline ``other``;
    None where they never come that close."""
    if len(way) == 0 or len(other) == 0:
        return None
    points = resample(way, SAMPLE_M)
    near = distances_to_polyline(points, other) < reach_m
    if not near.any():
        return None
    return float(arc_lengths(points)[int(np.argmax(near))])


def can_stop_before(distance_m: float, speed_mps: float, decel_mps2: float = COMFORT_DECEL_MPS2) -> bool:
    """Whether a driver ``distance_m`` [m] from its stop line at ``speed_mps`` stops before it
    braking at ``decel_mps2`` (one standing at the line does)."""
    return speed_mps * speed_mps / (2.0 * decel_mps2) <= max(distance_m, 0.0)


def way_through(via: str, shape_of: Callable[[str], FloatArray],
                next_of: Callable[[str], str | None]) -> FloatArray:
    """(n, 2) [m] the way through the junction of a link whose internal lane is ``via``: that lane
    and the internal lanes after it (a left turn's part beyond its waiting point)."""
    parts = [shape_of(via)]
    current: str | None = via
    while (current := next_of(current)) is not None and current.startswith(":"):
        parts.append(shape_of(current))
    return np.vstack(parts)


@dataclass(frozen=True)
class Caught:
    """One caught inside the junction: its remaining way [m] and half width [m]."""

    vehicle_id: str
    way: FloatArray
    half_width_m: float


class LettingOut:
    """Applies the rule (module docstring) at a junction whose links come in on ``incoming``
    (normal lanes); ``enabled`` False turns it off. ``exempt``: vehicles never held, and let out
    while they move however long they have been caught (the ego). ``waiting``: who waits now,
    with whom they wait for."""

    def __init__(self, incoming: Iterable[str], *, enabled: bool = True,
                 exempt: frozenset[str] = frozenset()) -> None:
        self.enabled = enabled
        self.incoming = frozenset(incoming)
        self.exempt = exempt
        self.waiting: dict[str, frozenset[str]] = {}
        self._caught_since: dict[str, float] = {}  # [s] when each was first seen caught
        self._check = Every(CHECK_EVERY_S)
        self._shapes: dict[str, FloatArray] = {}
        self._ways: dict[str, FloatArray] = {}
        self._lengths: dict[str, float] = {}

    def _shape(self, session: SumoSession, lane: str) -> FloatArray:
        shape = self._shapes.get(lane)
        if shape is None:
            shape = self._shapes[lane] = session.lane_shape(lane)
        return shape

    def _lane_length(self, session: SumoSession, lane: str) -> float:
        length = self._lengths.get(lane)
        if length is None:
            length = self._lengths[lane] = session.lane_length(lane)
        return length

    def _way_through(self, session: SumoSession, via: str) -> FloatArray:
        way = self._ways.get(via)
        if way is None:
            way = self._ways[via] = way_through(via, lambda lane: self._shape(session, lane),
                                                session.lane_next)
        return way

    def update(self, session: SumoSession, caught_ids: Callable[[], Iterable[str]], *,
               abnormal: frozenset[str] = frozenset()) -> None:
        """``caught_ids``: gives the vehicles (the ego among them, when it is) inside the junction
        whose movement's light is no longer green now, asked only when the rule looks;
        ``abnormal``: drivers the rule leaves alone."""
        if not self.enabled:
            return
        now = session.time_s
        if not self._check.due(now):
            return
        caught_now = set(caught_ids())
        self._caught_since = {vid: self._caught_since.get(vid, now) for vid in caught_now}
        moving = {vid for vid in self._caught_since.keys() & self.exempt
                  if session.vehicle_pose(vid)[3] > MOVING_MPS}
        let_out = [vid for vid, since in self._caught_since.items()
                   if now - since <= LET_OUT_FOR_S + 1e-9 or vid in moving]
        caught = [self._caught(session, vid) for vid in let_out] if let_out else []
        waiting: dict[str, frozenset[str]] = {}
        if caught:
            caught_moving = [c for c in caught if c.vehicle_id in moving]
            lanes = session.vehicle_lanes()
            for vid, lane in lanes.items():
                if vid in self.exempt or vid in abnormal or vid in caught_now:
                    continue
                if lane in self.incoming:
                    waits_for = self._waits_for(session, vid, lane, caught)
                elif caught_moving and lane.startswith(":"):
                    waits_for = self._waits_inside(session, vid, lane, caught_moving)
                else:
                    continue
                if waits_for:
                    waiting[vid] = waits_for
        for vid in waiting.keys() - self.waiting.keys():
            session.hold_vehicle(vid, HOLDER)
        gone = self.waiting.keys() - waiting.keys()
        if gone:
            alive = set(session.vehicle_ids)
            for vid in gone & alive:
                session.release_vehicle(vid, HOLDER)
        self.waiting = waiting

    def _caught(self, session: SumoSession, vid: str) -> Caught:
        lane = session.vehicle_lane(vid)
        way = remaining_way(lane, session.vehicle_lane_position(vid), lambda name: self._shape(session, name),
                            session.lane_next) if lane.startswith(":") else np.empty((0, 2))
        return Caught(vid, way, 0.5 * session.vehicle_size(vid)[1])

    def _waits_for(self, session: SumoSession, vid: str, lane: str, caught: list[Caught]) -> frozenset[str]:
        """Whom of ``caught`` the driver ``vid`` on incoming ``lane`` waits for (empty: no one)."""
        distance = self._lane_length(session, lane) - session.vehicle_lane_position(vid)
        if distance > APPROACH_M:
            return frozenset()
        if vid not in self.waiting and not can_stop_before(distance, session.vehicle_pose(vid)[3]):
            return frozenset()
        link = session.vehicle_next_link(vid)
        if link is None or not link[0] or link[1] not in GREEN_LINK_STATES:
            return frozenset()
        way = self._way_through(session, link[0])
        half_width = 0.5 * session.vehicle_size(vid)[1]
        return frozenset(c.vehicle_id for c in caught
                         if ways_meet(way, c.way, half_width + c.half_width_m + WAY_MARGIN_M))

    def _waits_inside(self, session: SumoSession, vid: str, lane: str, moving: list[Caught]) -> frozenset[str]:
        """Whom of the caught ones that move the driver ``vid``, inside the junction on its green
        (on internal ``lane``), waits for: those whose way its own meets ahead of its front, where
        it can still stop short of the meeting braking at :data:`COMFORT_DECEL_MPS2` (one already
        waiting goes on waiting while their ways meet ahead)."""
        way = remaining_way(lane, session.vehicle_lane_position(vid), lambda name: self._shape(session, name),
                            session.lane_next)
        half_width = 0.5 * session.vehicle_size(vid)[1]
        speed = session.vehicle_pose(vid)[3]
        waits_for = []
        for c in moving:
            meeting = distance_to_meeting(way, c.way, half_width + c.half_width_m + WAY_MARGIN_M)
            if meeting is not None and (vid in self.waiting or can_stop_before(meeting, speed)):
                waits_for.append(c.vehicle_id)
        return frozenset(waits_for)


def incoming_lanes(controlled: Iterable[Iterable[tuple[str, str, str]]]) -> frozenset[str]:
    """The normal lanes a traffic light's links come in on (its controlled links' from-lanes)."""
    return frozenset(src for triples in controlled for src, _, _ in triples if not src.startswith(":"))

