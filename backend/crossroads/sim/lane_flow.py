"""Per entrance lane: how much of its demand a lane serves, and whether its green could serve more.

The world's flow (:mod:`crossroads.sim.flow`) says how much of the demand crosses; this says where
the rest waits and why. For each entrance lane of the junction, over the window:

- its demand (vehicles the plan scheduled to depart on it) and what crossed its stop line, per hour;
- the share of the window its main movement had green (straight on where it has a straight
  movement, otherwise any of its movements);
- its **discharge while queued**: vehicles that crossed per hour of green while at least
  :data:`QUEUED_HALTING` stood on the lane — a lane whose queue leaves at this rate and no faster
  is held at its head (a left-turner waiting for a gap, a right-turner yielding to a walk), not
  short of green;
- how many of its greens ended with :data:`OVERSATURATED_HALTING` or more vehicles still standing
  on it: a green that leaves a queue behind served less than came. A lane whose greens end so in
  most cycles is oversaturated — its demand exceeds what its movement can carry in its green —
  and no rule of the world short of another signal program or demand makes it flow as demanded.

:class:`LaneFlowCounter` is fed a running session every step; :func:`main_link_indices` and
:func:`lane_flows` are pure.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

from crossroads.network.road import Junction
from crossroads.sim.sumo import GREEN_LINK_STATES, SumoSession

QUEUED_HALTING = 2  # vehicles standing on the lane for its green to count as discharging a queue
OVERSATURATED_HALTING = 3  # vehicles still standing on the lane when its green ends: a queue left behind


@dataclass(frozen=True)
class LaneFlow:
    """One entrance lane over the window (module docstring)."""

    lane: str
    turns: tuple[str, ...]  # the turns its connections allow ("left", "straight", "right", ...)
    demand_h: float  # [veh/h] scheduled to depart on it; nan where the plan starts upstream of it
    crossed_h: float  # [veh/h] crossed its stop line
    green_share: float  # [-] of the window its main movement had green
    queued_discharge_h: float  # [veh/h of green] while a queue stood on it; nan if none ever did
    greens: int  # greens of its main movement that ended within the window
    greens_ending_queued: int  # of those, ended with OVERSATURATED_HALTING or more standing

    @property
    def oversaturated_share(self) -> float:
        """[-] share of its greens that left a queue behind; nan without a green."""
        return self.greens_ending_queued / self.greens if self.greens else float("nan")

    @property
    def ratio(self) -> float:
        """Crossed / demand; nan without a known demand."""
        return self.crossed_h / self.demand_h if self.demand_h else float("nan")


def main_link_indices(junction: Junction) -> dict[str, tuple[int, ...]]:
    """Per entrance lane, the light's link indices of its main movement: its straight
    connections where it has any, else all of its connections (lanes without a light: none)."""
    out: dict[str, tuple[int, ...]] = {}
    for approach in junction.approaches:
        for lane in approach.entrance_lanes:
            links = [(c.turn, c.tl_link_index) for c in approach.connections
                     if c.from_lane == lane.id and c.tl_link_index is not None]
            straight = [index for turn, index in links if turn == "straight"]
            out[lane.id] = tuple(sorted(set(straight or [index for _, index in links])))
    return out


def lane_flows(lanes: Iterable[tuple[str, tuple[str, ...]]], *, window_s: float,
               demand: Mapping[str, int], known_demand: frozenset[str], crossed: Mapping[str, int],
               green_s: Mapping[str, float], queued_green_s: Mapping[str, float],
               crossed_queued: Mapping[str, int], greens: Mapping[str, int],
               greens_queued: Mapping[str, int]) -> tuple[LaneFlow, ...]:
    """The counts of a window (vehicles, seconds) as :class:`LaneFlow` rates, lane by lane."""
    per_h = 3600.0 / window_s
    return tuple(LaneFlow(
        lane=lane, turns=turns,
        demand_h=demand.get(lane, 0) * per_h if lane in known_demand else math.nan,
        crossed_h=crossed.get(lane, 0) * per_h,
        green_share=green_s.get(lane, 0.0) / window_s,
        queued_discharge_h=(3600.0 * crossed_queued.get(lane, 0) / queued_green_s[lane]
                            if queued_green_s.get(lane) else math.nan),
        greens=greens.get(lane, 0), greens_ending_queued=greens_queued.get(lane, 0),
    ) for lane, turns in lanes)


class LaneFlowCounter:
    """Counts, step by step, what :func:`lane_flows` needs for every entrance lane of
    ``junction`` (the light ``junction.tl_id``) from ``window_start_s`` of simulated time on.
    ``counted``: which vehicles count as crossing (the demand's cars, not the cyclists that share
    a car lane); every vehicle standing on a lane counts in its queue."""

    def __init__(self, junction: Junction, window_start_s: float,
                 counted: Callable[[str], bool] = lambda _vid: True) -> None:
        self.tl_id = junction.tl_id
        self.counted = counted
        self.window_start_s = window_start_s
        self.links = main_link_indices(junction)
        self.turns = {lane.id: tuple(sorted(a.turns_of(lane.id))) for a in junction.approaches
                      for lane in a.entrance_lanes}
        self._on_lane: dict[str, set[str]] = {lane: set() for lane in self.links}
        self._was_green: dict[str, bool] = dict.fromkeys(self.links, False)
        self.crossed: Counter[str] = Counter()
        self.crossed_queued: Counter[str] = Counter()
        self.green_s: Counter[str] = Counter()
        self.queued_green_s: Counter[str] = Counter()
        self.greens: Counter[str] = Counter()
        self.greens_queued: Counter[str] = Counter()

    def update(self, session: SumoSession, step_s: float) -> None:
        """Count the step SUMO has just made (``step_s`` long)."""
        counting = session.time_s > self.window_start_s
        state = session.tl_state(self.tl_id) if self.tl_id else ""
        for lane, indices in self.links.items():
            now = set(session.lane_vehicle_ids(lane))
            # crossed its stop line (or changed lane: rare at the line)
            left = sum(1 for vid in self._on_lane[lane] - now if self.counted(vid))
            self._on_lane[lane] = now
            green = bool(indices) and any(state[k] in GREEN_LINK_STATES for k in indices)
            if counting:
                halting = session.lane_halting(lane)
                self.crossed[lane] += left
                if green:
                    self.green_s[lane] += step_s
                    if halting >= QUEUED_HALTING:
                        self.queued_green_s[lane] += step_s
                        self.crossed_queued[lane] += left
                elif self._was_green[lane]:
                    self.greens[lane] += 1
                    self.greens_queued[lane] += halting >= OVERSATURATED_HALTING
            self._was_green[lane] = green

    def report(self, window_s: float, demand: Mapping[str, int], known_demand: frozenset[str]) -> tuple[LaneFlow, ...]:
        """The window's :class:`LaneFlow` per entrance lane; ``demand``: vehicles scheduled per
        lane over the window, known for the lanes in ``known_demand``."""
        return lane_flows(((lane, self.turns.get(lane, ())) for lane in self.links), window_s=window_s,
                          demand=demand, known_demand=known_demand, crossed=self.crossed,
                          green_s=self.green_s, queued_green_s=self.queued_green_s,
                          crossed_queued=self.crossed_queued, greens=self.greens,
                          greens_queued=self.greens_queued)
