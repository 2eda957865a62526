"""Mixed traffic demand for one junction (SPEC §2), written as a SUMO ``.rou.xml``.

Per entrance lane: vehicles 400/h, cyclists 100/h, pedestrians 100/h by default. Every departure
time is drawn here from the scenario seed (a Poisson process: exponential gaps with numpy), so the
demand is fully determined by the seed and never depends on SUMO's RNG. Departures start at t = 0
so that the world's warm-up fills the intersection.

* Vehicles: per leg, ``n_lanes × rate`` split over its turns by :attr:`TrafficDemand.turn_shares`
  (left 10 %, straight 70 %, right 20 % by default; U-turns are left out), each departing on a lane
  that serves its turn, the lanes' loads levelled; or, with ``turn_shares=None``, each entrance
  lane its own rate split evenly over that lane's turns. ``departLane`` is that lane.
* Cyclists: per leg, ``n_lanes × rate`` on the bike lane if the leg has one, else on the rightmost
  lane that admits bicycles (a leg with none gets no cyclists, said in the plan's ``notes``), to
  the exits the leg's car connections reach whose edge admits bicycles — straight on and right by
  default (:attr:`TrafficDemand.cyclist_left_turns`).
* Pedestrians: per leg, ``n_lanes × rate`` walking from the leg's sidewalk near the junction to a
  sidewalk of another leg that the junction's walking areas and crossings connect it to
  (:func:`walkable_pairs`, read from the net's pedestrian connections; SUMO's router takes them
  over those crossings, and refuses a walk between sidewalks they do not join: "No connection
  found"). Nets without sidewalks or crossings (cologne1) get no pedestrians, nor a leg whose
  sidewalk reaches no other; :class:`DemandPlan` ``notes`` says so.

Trips (``from``/``to`` edges) rather than fixed routes: inside clustered junctions the exit edge
need not follow the entrance edge directly, and SUMO's router finds the path through.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from crossroads.constants import (
    CYCLISTS_PER_HOUR_PER_LANE,
    PEDESTRIANS_PER_HOUR_PER_LANE,
    VEHICLES_PER_HOUR_PER_LANE,
)
from crossroads.network.road import TASKS, Approach, Junction
from crossroads.network.netxml import internal_edge_owner, read_net_xml

log = logging.getLogger(__name__)

CAR_TYPE = "car"
BIKE_TYPE = "bicycle"
PED_TYPE = "pedestrian"

# vType attributes. (choice) Cars: Krauss with sigma 0.5 (SUMO's default imperfection); their
# speed factor never exceeds 1, so a normal driver never drives over the limit — over-speeding is
# only what sim/abnormal.py makes on purpose (SPEC §8).
# (choice) Cars and bicycles have SUMO's impatience 0.5 (its default is 0): a driver waiting to turn
# across oncoming traffic accepts a gap that makes an oncoming vehicle brake, as people do. With 0,
# the paper's permissive left turns (left and straight green together, SPEC §2) jam under 400 veh/h
# per lane: left-turners wait inside the junction for gaps that do not come, and in 9 of 10 seeded
# nominal left-turn runs on c_three_lane the vehicle ahead of the ego stood for the whole 60 s
# episode, so no driver could pass (the rule controller passed 1 of 10). With 0.5 it stood in 1 of
# 10 and the rule controller passed 8.
IMPATIENCE = 0.5
VTYPES_XML = f"""    <vType id="{CAR_TYPE}" vClass="passenger" length="4.5" width="1.8" minGap="2.5"
           accel="2.6" decel="4.5" sigma="0.5" speedFactor="normc(0.95,0.05,0.8,1.0)"
           impatience="{IMPATIENCE}" carFollowModel="Krauss" laneChangeModel="LC2013" color="yellow"/>
    <vType id="{BIKE_TYPE}" vClass="bicycle" length="1.6" width="0.65" minGap="0.5"
           maxSpeed="5.5" accel="1.2" decel="3.0" sigma="0.5" speedFactor="normc(1.0,0.1,0.7,1.0)"
           impatience="{IMPATIENCE}" color="green"/>
    <vType id="{PED_TYPE}" vClass="pedestrian" length="0.25" width="0.5" maxSpeed="1.4"
           speedFactor="normc(1.0,0.1,0.6,1.3)" color="blue"/>
"""

DEFAULT_TURN_SHARES = (0.1, 0.7, 0.2)  # (left, straight, right) of an approach's vehicles: TrafficDemand

PED_START_BEFORE_JUNCTION_M = (3.0, 25.0)  # [m] pedestrians start this far from the junction
PED_END_AFTER_JUNCTION_M = (3.0, 25.0)  # [m] and walk this far past it on the target sidewalk


@dataclass(frozen=True)
class TrafficDemand:
    """Traffic per entrance lane [per hour]; 0 means no such traffic."""

    vehicles_per_hour: float = VEHICLES_PER_HOUR_PER_LANE  # [veh/h] per entrance lane
    cyclists_per_hour: float = CYCLISTS_PER_HOUR_PER_LANE  # [bic/h] per entrance lane
    pedestrians_per_hour: float = PEDESTRIANS_PER_HOUR_PER_LANE  # [ped/h] per entrance lane
    # (choice) Whether cyclists turn left. SUMO models a cyclist's left turn from the rightmost
    # lane as a car's, across every lane of its leg into the left-turners' path; at the paper's
    # densities these cyclists and the left-turners waited on each other inside the junction: on
    # c_three_lane 34-48 % of the cyclists got through (measured with sim/flow.py), and the
    # queues behind stood for minutes. Without left turns (their share rides straight on or
    # right instead, as many cities route cyclists' left turns indirectly) 98-102 % did (two
    # seeds, 900 s each). The cyclist count stays the paper's.
    cyclist_left_turns: bool = False
    # (choice) Vehicles' turns: the approach's rate (per entrance lane × its entrance lanes)
    # split over its turns by these shares (left, straight, right), each turn over its lanes
    # levelling their loads (lane_split); None: each entrance lane its own rate, split evenly
    # over that lane's turns. With None a left-only lane carries 400 left-turners an hour, while
    # permissive left turns (SPEC §2) across 600 oncoming vehicles an hour get through mostly in
    # the clearance at the end of each green (two left-turners seen clearing there): on
    # c_three_lane 4-10 % of them crossed in 900 s and the queues grew without end (sim/flow.py).
    # Urban left-turn shares of about a tenth are closer to what such a junction can serve.
    turn_shares: tuple[float, float, float] | None = DEFAULT_TURN_SHARES

    def __post_init__(self) -> None:
        if self.turn_shares is not None and (
                len(self.turn_shares) != 3 or not all(math.isfinite(x) and x >= 0.0 for x in self.turn_shares)
                or sum(self.turn_shares) <= 0.0):
            raise ValueError(f"TrafficDemand.turn_shares must be 3 shares >= 0 (left, straight, right) "
                             f"with a positive sum, got {self.turn_shares}")
        for name in ("vehicles_per_hour", "cyclists_per_hour", "pedestrians_per_hour"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"TrafficDemand.{name} must be a finite number >= 0, got {value}")


NO_TRAFFIC = TrafficDemand(vehicles_per_hour=0.0, cyclists_per_hour=0.0, pedestrians_per_hour=0.0)
"""An empty road: the ego alone (tracking benchmarks, tests)."""


@dataclass(frozen=True)
class Departure:
    """One vehicle, cyclist or pedestrian of the plan."""

    id: str
    kind: str  # "vehicle" | "cyclist" | "pedestrian"
    depart_s: float  # [s]
    from_edge: str
    to_edge: str
    depart_lane: int | None = None  # vehicles and cyclists
    turn: str | None = None  # vehicles and cyclists: "left" | "straight" | "right"
    depart_pos_m: float | None = None  # pedestrians: position on the from-edge [m]
    arrival_pos_m: float | None = None  # pedestrians: position on the to-edge [m]
    speed_factor: float | None = None  # vehicles: their own instead of their type's (injected ones)


@dataclass(frozen=True)
class DemandPlan:
    """Everything a route file will contain, sorted by departure, plus what was left out."""

    departures: tuple[Departure, ...]
    notes: tuple[str, ...] = field(default=())

    def count(self, kind: str) -> int:
        return sum(1 for d in self.departures if d.kind == kind)


def poisson_times(rng: np.random.Generator, rate_per_hour: float, duration_s: float) -> np.ndarray:
    """Departure times [s] in [0, duration_s) of a Poisson process of the given rate."""
    if rate_per_hour <= 0.0 or duration_s <= 0.0:
        return np.zeros(0)
    mean_gap_s = 3600.0 / rate_per_hour
    # Draw enough gaps in one go (mean + 6 sigma of the count), then cut at the horizon.
    expected = duration_s / mean_gap_s
    n = int(expected + 6.0 * math.sqrt(expected) + 10)
    times = np.cumsum(rng.exponential(mean_gap_s, size=n))
    return times[times < duration_s]


def _exits_by_turn(approach: Approach, lane_id: str | None = None) -> dict[str, str]:
    """Turn → exit edge of an approach's car connections (of one lane if given); no U-turns."""
    out: dict[str, str] = {}
    for c in approach.connections:
        if c.turn in TASKS and (lane_id is None or c.from_lane == lane_id):
            out.setdefault(c.turn, c.to_lane.rsplit("_", 1)[0])
    return out


def _vehicles_per_lane(rng: np.random.Generator, a: Approach, rate: float,
                       duration_s: float) -> list[Departure]:
    """Every entrance lane its own ``rate``, split evenly over the lane's turns."""
    deps = []
    for lane in a.entrance_lanes:
        turns = _exits_by_turn(a, lane.id)
        if not turns:
            continue
        names = sorted(turns)
        for t in poisson_times(rng, rate, duration_s):
            turn = names[int(rng.integers(len(names)))]
            deps.append(Departure("", "vehicle", float(t), a.incoming_edge, turns[turn],
                                  depart_lane=lane.index, turn=turn))
    return deps


def lane_split(a: Approach, volumes: dict[str, float]) -> dict[str, dict[int, float]]:
    """How each turn's volume [veh/h] spreads over the entrance lanes that serve it, levelling
    the lanes' loads: turns with fewer lanes first, each poured into its least-loaded lanes
    (water filling). Returns turn → {lane index: volume}."""
    lanes_of = {turn: [ln.index for ln in a.entrance_lanes if turn in _exits_by_turn(a, ln.id)]
                for turn in volumes}
    load = {ln.index: 0.0 for ln in a.entrance_lanes}
    split: dict[str, dict[int, float]] = {}
    for turn in sorted(volumes, key=lambda t: (len(lanes_of[t]), t)):
        lanes, left = lanes_of[turn], volumes[turn]
        split[turn] = dict.fromkeys(lanes, 0.0)
        while left > 1e-9 and lanes:
            low = min(load[i] for i in lanes)
            lowest = [i for i in lanes if load[i] - low < 1e-9]
            higher = [load[i] for i in lanes if load[i] - low >= 1e-9]
            room = (min(higher) - low) * len(lowest) if higher else left
            pour = min(left, room)
            for i in lowest:
                load[i] += pour / len(lowest)
                split[turn][i] += pour / len(lowest)
            left -= pour
    return split


def _vehicles_by_turn_shares(rng: np.random.Generator, a: Approach, rate: float,
                             shares: tuple[float, float, float], duration_s: float) -> list[Departure]:
    """The approach's ``rate × entrance lanes`` split over its turns by ``shares`` (left,
    straight, right; renormalised over the turns it has), each turn over its lanes by
    :func:`lane_split`."""
    exits = _exits_by_turn(a)
    weights = {turn: share for turn, share in zip(("left", "straight", "right"), shares)
               if turn in exits and share > 0.0}
    total = sum(weights.values())
    approach_rate = rate * len(a.entrance_lanes)
    if not weights or total <= 0.0 or approach_rate <= 0.0:
        return []
    split = lane_split(a, {turn: approach_rate * w / total for turn, w in weights.items()})
    cells = [(turn, lane, v) for turn, lanes in sorted(split.items()) for lane, v in sorted(lanes.items())]
    p = np.array([v for _, _, v in cells]) / approach_rate
    deps = []
    for t in poisson_times(rng, approach_rate, duration_s):
        turn, lane, _ = cells[int(rng.choice(len(cells), p=p))]
        deps.append(Departure("", "vehicle", float(t), a.incoming_edge, exits[turn],
                              depart_lane=lane, turn=turn))
    return deps


def _admits_bicycles(junction: Junction, edge_id: str) -> bool:
    """Whether an edge has a lane bicycles may use (an edge the junction does not describe: yes,
    SUMO's router decides)."""
    if any(b.edge_id == edge_id for b in junction.bike_lanes):
        return True
    lanes = [ln for ln in junction.lanes.values() if ln.edge_id == edge_id]
    return not lanes or any("bicycle" in ln.allowed_classes for ln in lanes)


def _cyclist_exits(junction: Junction, approach: Approach, *, left_turns: bool) -> dict[str, str]:
    """Turn → exit edge for the cyclists of an approach: exits that admit bicycles, left turns
    only when asked for (:attr:`TrafficDemand.cyclist_left_turns`)."""
    return {turn: edge for turn, edge in _exits_by_turn(approach).items()
            if (left_turns or turn != "left") and _admits_bicycles(junction, edge)}


def _has_pedestrian_network(junction: Junction) -> bool:
    return bool(junction.crossings) and bool(junction.sidewalks)


_WALKING_FUNCTIONS = frozenset({"walkingarea", "crossing"})


@lru_cache(maxsize=16)
def _walking_groups(net_file: Path, mtime_ns: int, node_ids: tuple[str, ...]) -> dict[str, int]:
    """Edge id → group number: edges in one group are joined on foot over the walking areas and
    crossings of ``node_ids`` (kept per net file and its modification time: a city net takes
    seconds to parse, and every episode draws its demand anew).

    SUMO writes a walking area's ties as connections: a sidewalk ending there (``from`` the
    sidewalk ``to`` the walking area), one starting there, a crossing leaving or reaching it.
    People walk either way, so each connection joins its two edges, both ways."""
    net = read_net_xml(net_file)
    nodes = set(node_ids)
    parent: dict[str, str] = {}

    def root(edge: str) -> str:
        while parent.setdefault(edge, edge) != edge:
            parent[edge] = parent[parent[edge]]
            edge = parent[edge]
        return edge

    def on_foot_here(edge_id: str) -> bool:
        edge = net.edges.get(edge_id)
        return (edge is not None and edge.function in _WALKING_FUNCTIONS
                and internal_edge_owner(edge_id, net.nodes) in nodes)

    for c in net.connections:
        if on_foot_here(c.from_edge) or on_foot_here(c.to_edge):
            parent[root(c.from_edge)] = root(c.to_edge)
    groups: dict[str, int] = {}
    return {edge: groups.setdefault(root(edge), len(groups)) for edge in list(parent)}


def walkable_pairs(junction: Junction, from_edges: list[str], to_edges: list[str]) -> dict[str, list[str]]:
    """For each of ``from_edges``, those of ``to_edges`` (another leg's) its sidewalk reaches over
    the junction's walking areas and crossings: where SUMO's router finds a walk, read from the
    net file without starting SUMO."""
    path = Path(junction.net_file).resolve()
    groups = _walking_groups(path, path.stat().st_mtime_ns, tuple(sorted(junction.node_ids or (junction.id,))))
    return {e: [t for t in to_edges if e in groups and groups[e] == groups.get(t)]
            for e in from_edges}


def build_plan(junction: Junction, demand: TrafficDemand, *, seed: int,
               duration_s: float) -> DemandPlan:
    """The demand of a junction for ``duration_s`` [s], drawn from ``seed`` (pure: it writes
    nothing, starts no SUMO, and reads only the pedestrian ties of the junction's net file)."""
    rng = np.random.default_rng(seed)
    deps: list[Departure] = []
    notes: list[str] = []

    for a in junction.approaches:
        if demand.turn_shares is None:
            deps += _vehicles_per_lane(rng, a, demand.vehicles_per_hour, duration_s)
        else:
            deps += _vehicles_by_turn_shares(rng, a, demand.vehicles_per_hour, demand.turn_shares,
                                             duration_s)
        # --- cyclists: per leg, on its bike lane or its rightmost lane that admits them
        exits = _cyclist_exits(junction, a, left_turns=demand.cyclist_left_turns)
        if exits and a.entrance_lanes and demand.cyclists_per_hour > 0:
            bike = next((b for b in junction.bike_lanes if b.edge_id == a.incoming_edge), None)
            if bike is not None:
                lane_index: int | None = bike.index
            else:  # the rightmost car lane that admits bicycles (index 0 may be a sidewalk)
                lane_index = next((ln.index for ln in a.entrance_lanes
                                   if "bicycle" in ln.allowed_classes), None)
            if lane_index is None:
                notes.append(f"no cyclists from {a.incoming_edge!r}: none of its lanes admits bicycles")
                continue
            names = sorted(exits)
            rate = demand.cyclists_per_hour * len(a.entrance_lanes)
            for t in poisson_times(rng, rate, duration_s):
                turn = names[int(rng.integers(len(names)))]
                deps.append(Departure("", "cyclist", float(t), a.incoming_edge, exits[turn],
                                      depart_lane=lane_index, turn=turn))

    # --- pedestrians: from a leg's sidewalk (near the junction) to another leg's sidewalk
    if demand.pedestrians_per_hour > 0:
        if not _has_pedestrian_network(junction):
            notes.append(
                f"no pedestrians: junction {junction.id!r} of {junction.net_file} has "
                f"{len(junction.sidewalks)} sidewalks and {len(junction.crossings)} crossings"
            )
        else:
            walks = {lane.edge_id: lane for lane in junction.sidewalks}
            legs = [a for a in junction.approaches if a.incoming_edge in walks]
            targets = [a.outgoing_edge for a in junction.approaches
                       if a.outgoing_edge is not None and a.outgoing_edge in walks]
            reach = walkable_pairs(junction, [a.incoming_edge for a in legs], targets)
            stranded: list[str] = []
            for a in legs:
                start = walks[a.incoming_edge]
                choices = [e for e in reach[a.incoming_edge] if e != a.outgoing_edge]
                if not choices:
                    stranded.append(a.incoming_edge)
                    continue
                rate = demand.pedestrians_per_hour * max(1, len(a.entrance_lanes))
                for t in poisson_times(rng, rate, duration_s):
                    to_edge = choices[int(rng.integers(len(choices)))]
                    end = walks[to_edge]
                    before = rng.uniform(*PED_START_BEFORE_JUNCTION_M)
                    after = rng.uniform(*PED_END_AFTER_JUNCTION_M)
                    deps.append(Departure(
                        "", "pedestrian", float(t), a.incoming_edge, to_edge,
                        depart_pos_m=max(0.0, start.length_m - before),
                        arrival_pos_m=min(end.length_m, after),
                    ))
            if not legs:
                notes.append(f"no pedestrians: no approach of {junction.id!r} has a sidewalk")
            elif stranded:
                notes.append(f"no pedestrians from {', '.join(map(repr, stranded))}: the walking areas "
                             f"and crossings of junction {junction.id!r} join its sidewalk to no "
                             "other leg's")

    deps.sort(key=lambda d: (d.depart_s, d.kind, d.from_edge, d.to_edge))
    counters = {"vehicle": 0, "cyclist": 0, "pedestrian": 0}
    prefix = {"vehicle": "veh", "cyclist": "bike", "pedestrian": "ped"}
    named = []
    for d in deps:
        named.append(Departure(f"{prefix[d.kind]}{counters[d.kind]}", d.kind, round(d.depart_s, 2),
                               d.from_edge, d.to_edge, d.depart_lane, d.turn,
                               d.depart_pos_m, d.arrival_pos_m))
        counters[d.kind] += 1
    for note in notes:
        log.warning(note)
    return DemandPlan(tuple(named), tuple(notes))


def _xml_of(d: Departure) -> str:
    if d.kind == "pedestrian":
        return (f'    <person id={quoteattr(d.id)} type="{PED_TYPE}" depart="{d.depart_s:.2f}" '
                f'departPos="{d.depart_pos_m:.2f}">\n'
                f'        <walk from={quoteattr(d.from_edge)} to={quoteattr(d.to_edge)} '
                f'arrivalPos="{d.arrival_pos_m:.2f}"/>\n    </person>\n')
    vtype = CAR_TYPE if d.kind == "vehicle" else BIKE_TYPE
    factor = "" if d.speed_factor is None else f' speedFactor="{d.speed_factor:.4f}"'
    return (f'    <trip id={quoteattr(d.id)} type="{vtype}" depart="{d.depart_s:.2f}" '
            f'from={quoteattr(d.from_edge)} to={quoteattr(d.to_edge)} '
            f'departLane="{d.depart_lane}" departSpeed="max" departPos="base"{factor}/>\n')


def write_plan(plan: DemandPlan, path: str | Path) -> Path:
    """Write a plan as a SUMO route file (vTypes, then every departure in time order)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", encoding="utf-8") as f:
        f.write('<?xml version="1.0" encoding="UTF-8"?>\n<routes>\n')
        for note in plan.notes:
            f.write(f"    <!-- {note.replace('--', '- -')} -->\n")
        f.write(VTYPES_XML)
        for d in plan.departures:
            f.write(_xml_of(d))
        f.write("</routes>\n")
    return path


def write_routes(junction: Junction, demand: TrafficDemand, path: str | Path, *, seed: int,
                 duration_s: float) -> Path:
    """Draw the demand of ``junction`` from ``seed`` for ``duration_s`` [s] and write it to
    ``path`` (a ``.rou.xml``). What had to be left out is logged and written as XML comments."""
    return write_plan(build_plan(junction, demand, seed=seed, duration_s=duration_s), path)
