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

Checked every :data:`CHECK_EVERY_S` of simulated time.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from crossroads.sim.sumo import SPEED_MODE_CLEARING, SumoSession

CHECK_EVERY_S = 0.5  # [s] how often the rule looks
GREEN = frozenset("Gg")  # SUMO's green link states (with and without priority)


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


def caught(lane: str, state: str, links: dict[str, frozenset[int]]) -> bool:
    """Whether a vehicle on ``lane`` is inside the junction with no green left for its movement
    in the light's ``state`` string."""
    indices = links.get(lane)
    return indices is not None and not any(state[k] in GREEN for k in indices)


class JunctionClearing:
    """Applies the rule (module docstring) to the traffic light ``tl_id`` of a running session;
    ``enabled`` False turns it off. ``links``: :func:`session_movement_links` when the caller
    already has them (read from ``session`` otherwise). ``exempt``: vehicles it never touches (the
    ego)."""

    def __init__(self, session: SumoSession, tl_id: str, *, enabled: bool = True,
                 links: dict[str, frozenset[int]] | None = None,
                 exempt: frozenset[str] = frozenset()) -> None:
        self.enabled = enabled
        self.tl_id = tl_id
        self.exempt = exempt
        self.cleared: set[str] = set()
        self._next_check_s = 0.0
        self.links: dict[str, frozenset[int]] = {}
        if enabled:
            self.links = links if links is not None else session_movement_links(session, tl_id)

    def update(self, session: SumoSession) -> None:
        """Let the vehicles caught inside the junction now clear it (at most once per
        :data:`CHECK_EVERY_S`)."""
        if not self.enabled:
            return
        now = session.time_s
        if now + 1e-9 < self._next_check_s:
            return
        self._next_check_s = now + CHECK_EVERY_S
        state = session.tl_state(self.tl_id)
        lanes = session.vehicle_lanes()
        for vid, lane in lanes.items():
            if vid not in self.cleared and vid not in self.exempt and caught(lane, state, self.links):
                session.set_speed_mode(vid, SPEED_MODE_CLEARING)
                self.cleared.add(vid)
        if len(self.cleared) > 4096:  # forget the long gone, keep the set small
            self.cleared &= lanes.keys()
