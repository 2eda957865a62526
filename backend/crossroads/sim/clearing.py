"""Vehicles caught inside the junction by the end of their green clear it, the world's rule.

With the paper's permissive left turns, left-turners wait for gaps in the oncoming stream at
their waiting point inside the junction. SUMO lets them go once the oncoming stream has stopped,
but only as its junction model sees the links they still have to cross: after their green they
went on yielding, now to the cross street's traffic, which had green and in turn waited for
them standing across its way. On ``c_three_lane`` (no ego, 900 s after the warm-up, base seed
20261206) the cross street's outer lane stood through whole greens that way: its first car at the
stop line for 500 s, and the right-turners of that lane behind it (0 of 50 crossed).

The rule, as drivers do it: a vehicle (car or bicycle; never the ego, which its own driver
steers) on one of the junction's internal lanes when the light of its movement is no longer
green drives on regardless of the junction's right of way (SUMO's speed mode without the right
of way at intersections, :data:`crossroads.sim.sumo.SPEED_MODE_CLEARING`); it still keeps its
distance to whoever is ahead of it, and SUMO's other drivers still wait for a vehicle inside the
junction. Every route ends past the junction, so a vehicle keeps that mode to its end.

That still leaves knots: on the large junctions (`e_irregular_oblique`, `f_irregular_wide`) caught
vehicles of both axes stood inside the junction for 39–75 s, each yielding to another already in
it, until the gridlock breaker took them out, and the cross street's first cars waited at their
lines on green behind them. So, second, as drivers sort such a knot out: a caught vehicle that has
stood :data:`THROUGH_AFTER_S` goes first once its whole remaining way through the junction (and
:data:`EXIT_REACH_M` into its exit) is clear — no one's footprint, the ego's included, within its
half width plus :data:`WAY_MARGIN_M` of that way, now or at :data:`WAY_TIMES_S` ahead at their
speed and heading — with SUMO's speed mode that no longer yields to those already inside the
junction (:data:`crossroads.sim.sumo.SPEED_MODE_CLEARING_THROUGH`). It keeps its distance to the
car ahead on its own lane; once anyone comes into its way it yields again (back to the clearing
mode) until it has stood :data:`THROUGH_AFTER_S` again. Measured on the six junctions (no ego,
900 s, base seeds 20261206, 7 and 8): docs/results/world.md.

Checked every :data:`CHECK_EVERY_S` of simulated time.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np

from crossroads.geometry import FloatArray, distances_to_polyline, footprint_points, sub_polyline
from crossroads.sim.cadence import Every
from crossroads.sim.sumo import (
    GREEN_LINK_STATES,
    SPEED_MODE_CLEARING,
    SPEED_MODE_CLEARING_THROUGH,
    SumoSession,
)

CHECK_EVERY_S = 0.5  # [s] how often the rule looks
THROUGH_AFTER_S = 5.0  # [s] standing caught inside the junction before a clear way lets it go first
STANDING_MPS = 0.1  # [m/s] below this a vehicle counts as standing (SUMO's halting speed)
WAY_MARGIN_M = 0.5  # [m] beyond its half width: how far the others' footprints keep from its way
EXIT_REACH_M = 5.0  # [m] how far into its exit lane its way is looked at
WAY_TIMES_S = (0.0, 1.0, 2.0)  # [s] the others are looked at now and this far ahead at their speed

# (x, y, heading [rad], speed [m/s], length, width [m]) of the ego, which the snapshot leaves out
Pose = tuple[float, float, float, float, float, float]


def movement_links(controlled: Iterable[Iterable[tuple[str, str, str]]],
                   successors: Callable[[str], tuple[str, ...]]) -> dict[str, frozenset[int]]:
    """For every internal lane of a traffic light's links, the link indices whose light its
    vehicles drove in on. ``controlled``: per link index, the (from, to, via) lane triples
    (SUMO's controlled links); ``successors``: an internal lane -> the lanes its links lead to,
    asked only of those lanes, to reach the internal lanes behind an internal junction (a left
    turn's part after its waiting point), which no link names."""
    links: dict[str, set[int]] = {}
    for index, triples in enumerate(controlled):
        for _, _, via in triples:
            if via:
                links.setdefault(via, set()).add(index)
    todo = list(links)
    while todo:
        lane = todo.pop()
        for nxt in successors(lane):
            if nxt.startswith(":") and nxt not in links:
                links[nxt] = links[lane]
                todo.append(nxt)
    return {lane: frozenset(indices) for lane, indices in links.items()}


def session_movement_links(session: SumoSession, tl_id: str) -> dict[str, frozenset[int]]:
    """:func:`movement_links` of traffic light ``tl_id`` read from a running session (a property
    of the net: the same for every episode on it)."""
    return movement_links(session.tl_controlled_links(tl_id), session.lane_successors)


def remaining_way(lane: str, position_m: float, shape_of: Callable[[str], FloatArray],
                  next_of: Callable[[str], str | None], exit_reach_m: float = EXIT_REACH_M) -> FloatArray:
    """(n, 2) [m] the way still ahead of a vehicle's front at ``position_m`` along internal lane
    ``lane``: the rest of that lane, the internal lanes after it (``next_of``: the lane a vehicle
    drives onto next, None at the end) and ``exit_reach_m`` of the first normal lane."""
    parts = [sub_polyline(shape_of(lane), position_m, np.inf)]
    current: str | None = lane
    while (current := next_of(current)) is not None:
        if not current.startswith(":"):
            parts.append(sub_polyline(shape_of(current), 0.0, exit_reach_m))
            break
        parts.append(shape_of(current))
    return np.vstack(parts)


def way_is_clear(way: FloatArray, reach_m: float, xs: FloatArray, ys: FloatArray, headings: FloatArray,
                 speeds: FloatArray, lengths: FloatArray, widths: FloatArray,
                 times_s: Sequence[float] = WAY_TIMES_S) -> bool:
    """Whether no footprint (centres, headings [rad], speeds, lengths, widths) comes within
    ``reach_m`` of the polyline ``way``, now or at ``times_s`` ahead at its speed and heading."""
    if len(xs) == 0:
        return True
    for t in times_s:
        px, py = footprint_points(xs + speeds * t * np.cos(headings), ys + speeds * t * np.sin(headings),
                                  headings, lengths, widths)
        if (distances_to_polyline(np.column_stack([px.ravel(), py.ravel()]), way) < reach_m).any():
            return False
    return True


def caught(lane: str, state: str, links: dict[str, frozenset[int]]) -> bool:
    """Whether a vehicle on ``lane`` is inside the junction with no green left for its movement
    in the light's ``state`` string."""
    indices = links.get(lane)
    return indices is not None and not any(state[k] in GREEN_LINK_STATES for k in indices)


class JunctionClearing:
    """Applies the rule (module docstring) to the traffic light ``tl_id`` of a running session;
    ``enabled`` False turns it off. ``links``: :func:`session_movement_links` when the caller
    already has them (read from ``session`` otherwise). ``exempt``: vehicles it never touches (the
    ego). ``through_after_s``: the second rule's standing time (None: the first rule only).
    ``cleared``: the vehicles it has caught; ``going_first``: those of them let through a knot now."""

    def __init__(self, session: SumoSession, tl_id: str, *, enabled: bool = True,
                 links: dict[str, frozenset[int]] | None = None,
                 exempt: frozenset[str] = frozenset(),
                 through_after_s: float | None = THROUGH_AFTER_S) -> None:
        self.enabled = enabled
        self.through_after_s = through_after_s
        self.tl_id = tl_id
        self.exempt = exempt
        self.cleared: set[str] = set()
        self.inside: list[str] = []  # of ``cleared``, those on an internal lane at the last check
        self.going_first: set[str] = set()
        self._stood_s: dict[str, float] = {}  # [s] caught inside the junction and standing
        self._check = Every(CHECK_EVERY_S)
        self.links: dict[str, frozenset[int]] = {}
        if enabled:
            self.links = links if links is not None else session_movement_links(session, tl_id)

    def update(self, session: SumoSession, ego: Pose | None = None) -> None:
        """Let the vehicles caught inside the junction now clear it, and one that stood in a knot
        with its way clear go first (at most once per :data:`CHECK_EVERY_S`). ``ego``: the ego's
        pose, which the snapshot leaves out and no one's way may cross."""
        if not self.enabled:
            return
        now = session.time_s
        if not self._check.due(now):
            return
        state = session.tl_state(self.tl_id)
        lanes = session.vehicle_lanes()
        for vid, lane in lanes.items():
            if vid not in self.cleared and vid not in self.exempt and caught(lane, state, self.links):
                session.set_speed_mode(vid, SPEED_MODE_CLEARING)
                self.cleared.add(vid)
        self.inside = inside = [vid for vid in self.cleared if lanes.get(vid, "").startswith(":")]
        if inside and self.through_after_s is not None:
            self._sort_out_knots(session, inside, lanes, ego)
        if len(self.cleared) > 4096:  # forget the long gone, keep the sets small
            self.cleared &= lanes.keys()
            self.going_first &= self.cleared
            self._stood_s = {vid: s for vid, s in self._stood_s.items() if vid in self.cleared}

    def _sort_out_knots(self, session: SumoSession, inside: list[str], lanes: dict[str, str],
                        ego: Pose | None) -> None:
        """The second rule of the module docstring, for the caught vehicles ``inside`` the junction."""
        assert self.through_after_s is not None
        snap = session.snapshot()
        row = {str(pid): k for k, pid in enumerate(snap.ids)}
        for vid in inside:
            k = row.get(vid)
            if k is None:
                continue
            going = vid in self.going_first
            if not going:
                if snap.speed[k] >= STANDING_MPS:
                    self._stood_s[vid] = 0.0
                    continue
                self._stood_s[vid] = self._stood_s.get(vid, 0.0) + CHECK_EVERY_S
                if self._stood_s[vid] < self.through_after_s:
                    continue
            way = remaining_way(lanes[vid], session.vehicle_lane_position(vid), session.lane_shape,
                                session.lane_next)
            others = np.arange(len(snap.ids)) != k
            columns = [snap.x[others], snap.y[others], snap.heading[others], snap.speed[others],
                       snap.length[others], snap.width[others]]
            if ego is not None:
                columns = [np.append(column, value) for column, value in zip(columns, ego)]
            clear = way_is_clear(way, 0.5 * float(snap.width[k]) + WAY_MARGIN_M, *columns)
            if going and not clear:
                session.set_speed_mode(vid, SPEED_MODE_CLEARING)
                self.going_first.discard(vid)
                self._stood_s[vid] = 0.0
            elif not going and clear:
                session.set_speed_mode(vid, SPEED_MODE_CLEARING_THROUGH)
                self.going_first.add(vid)
