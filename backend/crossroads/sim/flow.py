"""How much traffic actually crosses the junction: flow against demand, per kind of participant.

A world can look busy and still serve little of its demand (a gridlock holds the queues) or serve
it only by removing participants. :func:`measure_flow` runs the warm world without the ego and
counts, per kind, the participants that crossed the junction and left the network (SUMO's arrivals:
every route of the demand ends past the junction) over a window after the warm-up, against the
departures the demand plan scheduled over the same window, both per entrance lane and hour, and
the participants the gridlock breaker removed; with ``per_lane``, every entrance lane's own
figures too (:mod:`crossroads.sim.lane_flow`: where the rest of the demand waits, and whether its
green could carry it).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from crossroads.constants import SIM_STEP_S
from crossroads.network.road import Junction
from crossroads.sim.clearing import JunctionClearing, session_movement_links
from crossroads.sim.gridlock import GridlockBreaker
from crossroads.sim.lane_flow import LaneFlow, LaneFlowCounter
from crossroads.sim.letting_out import LettingOut, incoming_lanes
from crossroads.sim.sumo import SumoSession
from crossroads.sim.traffic import TrafficDemand, build_plan, write_plan

KINDS = ("vehicle", "cyclist", "pedestrian")


@dataclass(frozen=True)
class KindFlow:
    """One kind's demand and flow over the window, per entrance lane and hour."""

    kind: str
    demand_per_lane_h: float  # scheduled departures
    crossed_per_lane_h: float  # arrivals past the junction
    removed: int  # by the gridlock breaker, over the window

    @property
    def ratio(self) -> float:
        """Flow / demand (1.0: everything scheduled got through); nan without demand."""
        return self.crossed_per_lane_h / self.demand_per_lane_h if self.demand_per_lane_h else float("nan")


@dataclass(frozen=True)
class FlowReport:
    window_s: float
    entrance_lanes: int
    kinds: tuple[KindFlow, ...]
    lanes: tuple[LaneFlow, ...] = ()  # per entrance lane, when measured (``per_lane``)

    def of(self, kind: str) -> KindFlow:
        return next(k for k in self.kinds if k.kind == kind)


def measure_flow(junction: Junction, demand: TrafficDemand, work_dir: Path, *, seed: int,
                 warmup_s: float, window_s: float, gridlock_stand_s: float | None,
                 junction_clearing: bool = True, let_out: bool = True, junction_lane_changes: bool = False,
                 per_lane: bool = False) -> FlowReport:
    """Run the world of ``junction`` with ``demand`` (seeded) for ``warmup_s`` + ``window_s`` [s],
    no ego, and measure its flow over the window (see the module's docstring); the gridlock
    breaker, the junction clearing (sim/clearing.py), the letting out (sim/letting_out.py) and
    the lane changes inside the junction as the world's; ``per_lane`` adds each entrance lane's
    figures (:class:`LaneFlow`)."""
    plan = build_plan(junction, demand, seed=seed, duration_s=warmup_s + window_s)
    routes = write_plan(plan, work_dir / "flow.rou.xml")
    kind_of = {d.id: d.kind for d in plan.departures}
    scheduled = Counter(d.kind for d in plan.departures if warmup_s <= d.depart_s < warmup_s + window_s)
    crossed: Counter[str] = Counter()
    removed: Counter[str] = Counter()
    breaker = GridlockBreaker(junction, gridlock_stand_s)
    with SumoSession().start(junction.net_file, [routes], seed=seed) as session:
        clearing = JunctionClearing(session, junction.tl_id, enabled=junction_clearing)
        if not junction_lane_changes:
            session.forbid_lane_changes(session_movement_links(session, junction.tl_id))
        letting_out = LettingOut(incoming_lanes(session.tl_controlled_links(junction.tl_id)),
                                 enabled=let_out and junction_clearing)
        lane_counter = (LaneFlowCounter(junction, warmup_s, lambda vid: kind_of.get(vid) == "vehicle")
                        if per_lane else None)
        alive: set[str] = set()
        for _ in range(int(round((warmup_s + window_s) / SIM_STEP_S))):
            session.step()
            clearing.update(session)
            letting_out.update(session, lambda: clearing.inside)
            if lane_counter is not None:
                lane_counter.update(session, SIM_STEP_S)
            counting = session.time_s > warmup_s
            gone = alive  # who was there before this step and is not any more: arrived or removed
            for r in breaker.update(session):
                gone.discard(r.participant)
                if counting:
                    removed[kind_of.get(r.participant, "vehicle")] += 1
            alive = set(session.vehicle_ids) | set(session.person_ids)
            if counting:
                for pid in gone - alive:
                    crossed[kind_of.get(pid, "vehicle")] += 1
    lanes = sum(len(a.entrance_lanes) for a in junction.approaches)
    per_lane_h = 3600.0 / window_s / max(lanes, 1)
    lane_flows: tuple[LaneFlow, ...] = ()
    if lane_counter is not None:
        entrance = {a.incoming_edge for a in junction.approaches}
        lane_demand = Counter(f"{d.from_edge}_{d.depart_lane}" for d in plan.departures
                              if d.kind == "vehicle" and d.from_edge in entrance and d.depart_lane is not None
                              and warmup_s <= d.depart_s < warmup_s + window_s)
        # a lane's demand is known where the approach's cars depart on its own edge (the
        # catalogue's nets); on a real net they may start upstream of it
        departing = {d.from_edge for d in plan.departures if d.kind == "vehicle"}
        known = frozenset(lane.id for a in junction.approaches if a.incoming_edge in departing
                          for lane in a.entrance_lanes)
        lane_flows = lane_counter.report(window_s, lane_demand, known)
    return FlowReport(window_s, lanes, tuple(
        KindFlow(kind, scheduled[kind] * per_lane_h, crossed[kind] * per_lane_h, removed[kind])
        for kind in KINDS), lane_flows)

