"""Abnormal surrounding traffic of the generalization tests (SPEC §8).

* Speed limits: 25 km/h on the junction's internal lanes, 30 km/h on its approach and exit lanes.
* Overspeed: a share (15 %) of the vehicles going straight from the approach opposite the ego's
  exceed the limit by a fraction (10/20/50 %): their speed factor is set to ``1 + excess`` (SUMO's
  desired speed = speed factor × lane limit; normal cars of sim/traffic.py never go above 1).
* Rounding (choice, the paper gives no more detail): a share (10/20/50 %) of the left-turning cars
  of the opposite and the left approach violate their lane connection: on entering the junction
  they leave SUMO's internal lane and cut the corner on a cubic Bezier (geometry's construction
  with ρ = ROUNDING_RHO, near the chord) into the innermost lane of their exit edge, then SUMO
  drives them on from there. Their progress along the curve is the speed SUMO's own driver would
  choose, so they still yield and queue as before.
* Injection (a Crossroads addition, for timed tests and the failure search): ``count`` extra
  vehicles on the innermost straight lane of the opposite approach, each with its speed factor
  ``1 + excess`` from its insertion, departing so that the first is due at its stop line
  ``arrive_s`` after the episode starts (its lane's length at its own speed) and each next one
  ``headway_s`` later. They are added to the drawn demand (:func:`injected_departures`), which
  stays the same, and count as over-speeders in the traces.

Which vehicles are chosen is drawn from a seeded numpy Generator, one draw per candidate in
departure order, so a scenario seed gives the same abnormal vehicles every run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from crossroads.constants import (
    OVERSPEED_SHARE,
    SURROUNDING_LIMIT_INSIDE_MPS,
    SURROUNDING_LIMIT_OUTSIDE_MPS,
)
from crossroads.geometry import (
    FloatArray,
    arc_lengths,
    bezier_control_points_closed_form,
    sample_cubic_bezier,
)
from crossroads.network.road import Approach, Junction, Lane
from crossroads.sim.sumo import SumoSession
from crossroads.sim.traffic import DemandPlan, Departure

ROUNDING_RHO = 0.9  # [-] (choice) ρ of the rounding curve: close to the chord, it cuts the corner
ROUNDING_SAMPLE_M = 0.1  # [m] spacing of the sampled rounding curve
MAX_INJECTED = 5  # injected over-speeders a scenario may ask for
INJECTED_HEADWAY_S = 2.0  # [s] default time between two injected over-speeders
INJECTED_PREFIX = "inj"  # their vehicle ids: inj0, inj1, ... (the drawn demand's are veh0, ...)


@dataclass(frozen=True)
class Injection:
    """Over-speeders timed against the ego (see the module's docstring)."""

    count: int = 1
    arrive_s: float = 0.0  # [s] the first is due at the opposite stop line this long after the start
    excess: float = 0.0  # by how much they exceed the limit (0.5 = +50 %)
    headway_s: float = INJECTED_HEADWAY_S  # [s] between two of them

    def __post_init__(self) -> None:
        if not 0 <= self.count <= MAX_INJECTED:
            raise ValueError(f"Injection.count must be in [0, {MAX_INJECTED}]")
        if not (self.arrive_s >= 0.0 and self.excess >= 0.0 and self.headway_s > 0.0):
            raise ValueError("Injection.arrive_s and excess must be >= 0, headway_s > 0")


@dataclass(frozen=True)
class AbnormalConfig:
    """What abnormal behaviour a scenario asks for (shares and excess are fractions 0..1)."""

    overspeed_share: float = 0.0  # share of the opposite straight vehicles that over-speed
    overspeed_excess: float = 0.0  # by how much they exceed the limit (0.1 = +10 %)
    rounding_share: float = 0.0  # share of the candidate left-turners that cut into the inside lane
    injection: Injection | None = None  # over-speeders timed against the ego, or none
    limit_inside_mps: float = SURROUNDING_LIMIT_INSIDE_MPS  # [m/s]
    limit_outside_mps: float = SURROUNDING_LIMIT_OUTSIDE_MPS  # [m/s]
    apply_limits: bool = True  # set the §8 speed limits on the junction's lanes

    def __post_init__(self) -> None:
        for name in ("overspeed_share", "rounding_share"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"AbnormalConfig.{name} must be in [0, 1]")
        if self.overspeed_excess < 0.0:
            raise ValueError("AbnormalConfig.overspeed_excess must be >= 0")

    @classmethod
    def overspeed(cls, excess: float, share: float = OVERSPEED_SHARE) -> AbnormalConfig:
        return cls(overspeed_share=share, overspeed_excess=excess)

    @classmethod
    def rounding(cls, share: float) -> AbnormalConfig:
        return cls(rounding_share=share)


def _edge_of(lane_id: str) -> str:
    return lane_id.rsplit("_", 1)[0]


def opposite_approach(junction: Junction, ego: Approach) -> Approach:
    """The approach whose traffic comes head-on (heading closest to the ego's + π)."""
    others = [a for a in junction.approaches if a is not ego]
    return max(others, key=lambda a: -math.cos(a.heading_rad - ego.heading_rad))


def left_approach(junction: Junction, ego: Approach) -> Approach:
    """The approach coming from the ego's left (its traffic heads along the ego's heading − π/2)."""
    others = [a for a in junction.approaches if a is not ego]
    return max(others, key=lambda a: math.cos(a.heading_rad - (ego.heading_rad - math.pi / 2)))


def injection_lane(junction: Junction, ego: Approach) -> Lane | None:
    """Where injected over-speeders come from: the innermost entrance lane of the opposite
    approach that goes straight (None when none does)."""
    opp = opposite_approach(junction, ego)
    straight = {c.from_lane for c in opp.connections_for("straight")}
    lanes = [ln for ln in opp.entrance_lanes if ln.id in straight]
    return max(lanes, key=lambda ln: ln.index) if lanes else None


def injected_departures(junction: Junction, ego: Approach, injection: Injection | None, *,
                        episode_start_s: float, limit_mps: float) -> tuple[Departure, ...]:
    """The injected over-speeders' departures (pure): on the innermost lane of the opposite
    approach that goes straight, from the start of its edge, timed so that the first reaches the
    stop line ``injection.arrive_s`` after ``episode_start_s`` at ``limit_mps × (1 + excess)``
    (none departs before 0: one due earlier than its lane allows comes late)."""
    if injection is None or injection.count == 0:
        return ()  # most scenarios: no look at the junction
    lane = injection_lane(junction, ego)
    if lane is None:
        return ()
    opp = opposite_approach(junction, ego)
    exit_lane = next(c.to_lane for c in opp.connections_for("straight") if c.from_lane == lane.id)
    factor = 1.0 + injection.excess
    lead_s = lane.length_m / (limit_mps * factor)
    return tuple(
        Departure(f"{INJECTED_PREFIX}{k}", "vehicle",
                  round(max(0.0, episode_start_s + injection.arrive_s + k * injection.headway_s - lead_s), 2),
                  opp.incoming_edge, _edge_of(exit_lane), depart_lane=lane.index, turn="straight",
                  speed_factor=factor)
        for k in range(injection.count))


def with_departures(plan: DemandPlan, extra: tuple[Departure, ...]) -> DemandPlan:
    """``plan`` with ``extra`` departures merged in time order (SUMO reads a route file in order)."""
    if not extra:
        return plan
    merged = sorted((*plan.departures, *extra), key=lambda d: d.depart_s)  # stable: ties keep order
    return DemandPlan(tuple(merged), plan.notes)


def junction_lane_sets(junction: Junction, lane_ids: tuple[str, ...]) -> tuple[set[str], set[str]]:
    """(inside, outside) car lanes: internal lanes of the junction and its approach/exit lanes."""
    vias = {c.via_lane for a in junction.approaches for c in a.connections if c.via_lane}
    prefix = f":{junction.id}_"
    inside = {ln for ln in lane_ids if ln in vias or ln.startswith(prefix)}
    outside = set(junction.lanes) & set(lane_ids)
    return inside, outside


@dataclass
class _Rounding:
    """A rounding vehicle's custom path and its progress."""

    path: FloatArray  # (N, 2) centre positions [m]
    s: FloatArray  # arc length at each vertex [m]
    heading: FloatArray  # heading at each vertex [rad]
    progress_m: float = 0.0
    done: bool = False


@dataclass
class AbnormalTraffic:
    """Applies one :class:`AbnormalConfig` to a running session; call :meth:`update` every step.

    ``seed`` drives every choice (numpy Generator). ``abnormal_ids`` is the set of alive abnormal
    vehicles after the last update, for the trace.
    """

    junction: Junction
    ego_approach: Approach
    config: AbnormalConfig
    seed: int
    kinds: dict[str, str] = field(default_factory=dict)  # vehicle id -> "overspeed" | "rounding"
    _rng: np.random.Generator = field(init=False)
    _seen: set[str] = field(default_factory=set, init=False)
    _rounding: dict[str, _Rounding] = field(default_factory=dict, init=False)
    _overspeed_od: set[tuple[str, str]] = field(default_factory=set, init=False)
    _rounding_od: dict[tuple[str, str], Approach] = field(default_factory=dict, init=False)
    _vias: dict[tuple[str, str], set[str]] = field(default_factory=dict, init=False)

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        opp = opposite_approach(self.junction, self.ego_approach)
        left = left_approach(self.junction, self.ego_approach)
        for c in opp.connections_for("straight"):
            self._overspeed_od.add((opp.incoming_edge, _edge_of(c.to_lane)))
        for a in (opp, left):
            for c in a.connections_for("left"):
                self._rounding_od[(a.incoming_edge, _edge_of(c.to_lane))] = a
        for a in self.junction.approaches:
            for c in a.connections:
                if c.via_lane:
                    self._vias.setdefault((a.incoming_edge, _edge_of(c.to_lane)), set()).add(
                        c.via_lane)

    # --- set-up ------------------------------------------------------------------------------

    def apply_speed_limits(self, session: SumoSession) -> tuple[int, int]:
        """Set the §8 limits; returns how many (inside, outside) lanes were set."""
        inside, outside = junction_lane_sets(self.junction, session.lane_ids())
        for ln in sorted(inside):
            session.set_lane_max_speed(ln, self.config.limit_inside_mps)
        for ln in sorted(outside):
            session.set_lane_max_speed(ln, self.config.limit_outside_mps)
        return len(inside), len(outside)

    # --- every step ----------------------------------------------------------------------------

    @property
    def abnormal_ids(self) -> frozenset[str]:
        return frozenset(self.kinds)

    def _od(self, route: tuple[str, ...]) -> tuple[str, str] | None:
        """(entrance edge, exit edge) of a route through this junction, if it passes it."""
        for i, e in enumerate(route[:-1]):
            for j in range(i + 1, min(len(route), i + 4)):  # clusters: exits a few edges later
                if (e, route[j]) in self._vias:
                    return e, route[j]
        return None

    def _choose(self, session: SumoSession) -> None:
        cfg = self.config
        if not session.departed_last_step:
            return  # most steps: nobody new (the sets below cost more than the rest of the step here)
        if cfg.injection is not None:  # their speed factor came with them: only name them
            for vid in session.departed_last_step:
                if vid.startswith(INJECTED_PREFIX):
                    self.kinds[vid] = "overspeed"
        if not (cfg.overspeed_share > 0.0 or cfg.rounding_share > 0.0):
            return  # nominal traffic: nobody can be chosen (no draw either), skip SUMO's look-ups
        persons = set(session.person_ids)
        for vid in session.departed_last_step:
            if vid in self._seen or vid in persons or vid.startswith(INJECTED_PREFIX):
                continue
            self._seen.add(vid)
            if session.vehicle_class(vid) != "passenger":
                continue
            od = self._od(session.vehicle_route(vid))
            if od is None:
                continue
            # One draw per candidate, in departure order: deterministic given the seed.
            if od in self._overspeed_od and cfg.overspeed_share > 0.0:
                if self._rng.random() < cfg.overspeed_share:
                    session.set_speed_factor(vid, 1.0 + cfg.overspeed_excess)
                    self.kinds[vid] = "overspeed"
            elif od in self._rounding_od and cfg.rounding_share > 0.0:
                if self._rng.random() < cfg.rounding_share:
                    self.kinds[vid] = "rounding"

    def _rounding_path(self, session: SumoSession, vid: str, od: tuple[str, str]) -> _Rounding:
        """Bezier from the vehicle's pose now to the start of its exit edge's innermost lane."""
        x, y, heading, _ = session.vehicle_pose(vid)
        exit_leg = next((a for a in self.junction.approaches if a.outgoing_edge == od[1]), None)
        exits = exit_leg.exit_lanes if exit_leg is not None and exit_leg.exit_lanes else ()
        if exits:
            inner = exits[-1]  # rightmost first, so the last is the innermost lane
            target, theta_out = inner.start, inner.start_heading
            half = 0.5 * 4.5
            target = target + half * np.array([math.cos(theta_out), math.sin(theta_out)])
        else:  # unknown exit: fall back to SUMO's own lane end
            shape = session.lane_shape(f"{od[1]}_0")
            target, theta_out = shape[0], math.atan2(*(shape[1] - shape[0])[::-1])
        x1 = np.array([x, y])
        x2, x3 = bezier_control_points_closed_form(x1, target, heading, theta_out, ROUNDING_RHO)
        pts = sample_cubic_bezier(np.vstack([x1, x2, x3, target]), ROUNDING_SAMPLE_M)
        d = np.diff(pts, axis=0)
        hd = np.arctan2(d[:, 1], d[:, 0])
        return _Rounding(pts, arc_lengths(pts), np.concatenate([hd, hd[-1:]]))

    def _drive_rounding(self, session: SumoSession, alive: set[str]) -> None:
        dt = session.step_length_s
        for vid, kind in self.kinds.items():
            if kind != "rounding" or vid not in alive:
                continue
            state = self._rounding.get(vid)
            if state is None:
                lane = session.vehicle_lane(vid)
                if not lane.startswith(":"):
                    continue  # not inside the junction yet
                od = self._od(session.vehicle_route(vid))
                if od is None or lane not in self._vias.get(od, set()):
                    continue
                state = self._rounding[vid] = self._rounding_path(session, vid, od)
            if state.done:
                continue
            speed = max(0.0, session.speed_without_traci(vid))
            state.progress_m = min(state.s[-1], state.progress_m + speed * dt)
            k = int(np.searchsorted(state.s, state.progress_m))
            k = min(k, len(state.path) - 1)
            px, py = state.path[k]
            session.set_speed(vid, speed)
            session.move_vehicle(vid, float(px), float(py), float(state.heading[k]))
            if state.progress_m >= state.s[-1] - 1e-6:
                state.done = True
                session.set_speed(vid, -1.0)  # SUMO's driver takes over on the exit lane

    def update(self, session: SumoSession) -> frozenset[str]:
        """Choose among the newly departed, drive the rounding ones; returns ``abnormal_ids``."""
        self._choose(session)
        if not self.kinds:
            return self.abnormal_ids
        alive = set(session.vehicle_ids)
        for vid in [v for v in self.kinds if v not in alive]:
            del self.kinds[vid]
            self._rounding.pop(vid, None)
        if self.config.rounding_share > 0.0:
            self._drive_rounding(session, alive)
        return self.abnormal_ids
