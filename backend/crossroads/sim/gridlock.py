"""Breaking gridlocks inside the junction, the world's own rule.

With the paper's densities, permissive left turns and cyclists turning left like cars, SUMO's
participants can wait on each other inside the junction in a circle (a left-turner for a cyclist,
the cyclist for an oncoming car, that car for the left-turner, ...) that no signal change
dissolves: the queue behind them then stands for minutes, and no driver of the ego gets through.
SUMO would break it by teleporting after ``--time-to-teleport`` (300 s), which the world turns
off so that a scene stays as it is (sim/sumo.py).

The rule: a participant other than the ego that has stood (below 0.1 m/s, SUMO's waiting time)
on one of the junction's internal lanes — a pedestrian: on one of its crossings — for
``stand_s`` seconds is removed from the simulation. The ego is never removed. Every removal is
returned as a :class:`Removal`, which the world records as an episode event (traces, playback
and reports show it). A participant waiting at its stop line or on a walking area is not
inside the junction and is never removed: waiting for a red light is not a gridlock.

Checked once a second of simulated time (reading every participant's lane costs ~60 µs).
"""

from __future__ import annotations

from dataclasses import dataclass

from crossroads.network.road import Junction
from crossroads.sim.cadence import Every
from crossroads.sim.sumo import SumoSession

CHECK_EVERY_S = 1.0  # [s] how often the breaker looks


@dataclass(frozen=True)
class Removal:
    """One participant the breaker took out of the simulation."""

    time_s: float  # [s] SUMO time of the removal
    participant: str  # SUMO id
    stood_s: float  # [s] how long it had stood inside the junction
    lane: str  # the internal lane or crossing it stood on

    def to_event(self, episode_time_s: float) -> dict[str, object]:
        """The episode event of this removal (``t`` in the episode's time)."""
        return {"t": round(episode_time_s, 2), "event": "gridlock_removed",
                "value": {"id": self.participant, "stood_s": round(self.stood_s, 1),
                          "lane": self.lane}}


def internal_lane_prefixes(junction: Junction) -> tuple[str, ...]:
    """The id prefixes of the junction's internal lanes: ``:<node>_`` for every SUMO node it spans."""
    nodes = junction.node_ids or (junction.id,)
    return tuple(f":{node}_" for node in nodes)


def crossing_lane_prefixes(junction: Junction) -> tuple[str, ...]:
    """The lane id prefixes of the junction's pedestrian crossings (``<crossing edge>_``)."""
    return tuple(f"{c.id}_" for c in junction.crossings)


class GridlockBreaker:
    """Removes participants that stood ``stand_s`` inside ``junction`` (see the module's rule);
    ``stand_s`` None turns it off."""

    def __init__(self, junction: Junction, stand_s: float | None) -> None:
        if stand_s is not None and not stand_s > 0.0:
            raise ValueError(f"gridlock stand time must be > 0 s or None (off), got {stand_s}")
        self.stand_s = stand_s
        self._vehicle_lanes = internal_lane_prefixes(junction)
        self._person_lanes = crossing_lane_prefixes(junction)
        self._check = Every(CHECK_EVERY_S)

    def update(self, session: SumoSession) -> list[Removal]:
        """Remove whoever stood too long inside the junction now (at most once per
        :data:`CHECK_EVERY_S`); returns the removals."""
        if self.stand_s is None:
            return []
        now = session.time_s
        if not self._check.due(now):
            return []
        removals = []
        for pid, stood, lane in session.standing_on(self._vehicle_lanes, self._person_lanes):
            if stood >= self.stand_s:
                session.remove(pid)
                removals.append(Removal(now, pid, stood, lane))
        return removals
