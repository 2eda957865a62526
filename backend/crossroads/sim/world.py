"""The driving world: SUMO traffic and signals around an ego car driven by f_ego.

One :class:`World` per process runs any number of episodes one after another (libsumo restarts
cleanly). Every random choice flows from the episode's seed: the traffic's departures, SUMO's
drivers, the abnormal vehicles and the perception noise each get their own child of one
``numpy.random.SeedSequence(seed)``, so the same seed gives the same episode, frame for frame.

Each step: the controller's action moves the ego through f_ego (SPEC §5, 0.1 s); its pose and speed
are mirrored into SUMO (SUMO's drivers and pedestrians react to it); SUMO advances one step; the
outcome is judged on the true footprints; the ego perceives the others through its sensors with
Gaussian noise (SPEC §3).
"""

from __future__ import annotations

import math
import shutil
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
from shapely.geometry import LineString
from shapely.ops import unary_union

from crossroads.constants import EGO_LENGTH_M, EGO_WIDTH_M, SIM_STEP_S
from crossroads.geometry import FloatArray, arc_lengths
from crossroads.network.junction import read_junction
from crossroads.network.road import Approach, Junction, Lane
from crossroads.perception.noise import add_noise_unchecked
from crossroads.perception.sensors import DEFAULT_SENSORS, covered
from crossroads.planning import CandidatePath, plan_candidates
from crossroads.sim.abnormal import AbnormalTraffic, injected_departures, with_departures
from crossroads.sim.blocking import BlockedBy, held_whole_episode, nearest_barrier
from crossroads.sim.config import WorldConfig
from crossroads.sim.clearing import JunctionClearing, Pose, caught, remaining_way, session_movement_links
from crossroads.sim.courtesy import EGO_STANDING_MPS, Cars, Courtesy, Movers, watched_while_moving
from crossroads.sim.courtesy import NEAR_CAR_M as COURTESY_NEAR_CAR_M
from crossroads.sim.courtesy import CYCLIST_NEAR_M as COURTESY_CYCLIST_NEAR_M
from crossroads.sim.courtesy import NEAR_M as COURTESY_NEAR_M
from crossroads.sim.courtesy import SWEEP_NEAR_M
from crossroads.sim.ego import ego_step
from crossroads.sim.footprint import corner_coordinates, overlapping, reach, reject_distance
from crossroads.sim.gridlock import GridlockBreaker
from crossroads.sim.letting_out import LettingOut, incoming_lanes
from crossroads.sim.look_ahead import LookAhead, WayAhead, in_front
from crossroads.sim.observation import GroundTruth, LaneShapes, LightView, Observation, Perceived
from crossroads.sim.outcome import Outcome
from crossroads.sim.region import Region
from crossroads.sim.signals import (
    apply_start,
    live_light,
    movement_link,
    offset_for,
    phase_for_light,
    read_program,
)
from crossroads.sim.snapshot import KIND_CODE, Snapshot
from crossroads.sim.start import place_ego
from crossroads.sim.sumo import (
    SPEED_MODE_CLEARING,
    SPEED_MODE_CLEARING_THROUGH,
    SPEED_MODE_DEFAULT,
    SumoDriver,
    SumoSession,
)
from crossroads.sim.traffic import DemandPlan, build_plan, write_plan

EGO_ID = "ego"

OFF_ROAD_TOLERANCE_M = 0.5  # [m] a corner may overhang the drivable area this much (kerb, paint)
SPAWN_CLEARANCE_M = 6.0  # [m] participants this close to the ego's start are removed at entry
SPAWN_CLEAR_AHEAD_S = 3.0  # [s] ...and those within this much driving time ahead on its lane
# [s] ...and followers on its lane within this much of their own driving time behind it. Why: a car
# 6.1 m behind (centres) at 8.3 m/s, just outside SPAWN_CLEARANCE_M, rear-ended the ego 0.1 s into
# the episode (60 s nominal left, seed 1705482282): inserted 1.2 m ahead of it, the ego left SUMO's
# driver no time to brake
SPAWN_CLEAR_BEHIND_S = 1.0
# The start zone: for the ego's first START_ZONE_S nobody enters the stretch of road around its
# start, neither inserted by SUMO nor changing lanes into it; a driver who has just appeared can
# avoid neither. Why: on bs3d's short approach edge SUMO inserted a car at the edge's start 2.8 m
# (centres) behind the ego at 7.6 m/s, a collision 0.1 s into the episode (seed 673228719), and a
# car in the next lane changed into the gap the clearing (SPAWN_*) had just opened (issue 36).
# The zone runs along the ego's lead-in from START_ZONE_S of driving at its lane's speed limit
# (plus SPAWN_CLEARANCE_M) behind the ego to the cleared box ahead of it, and
# START_ZONE_HALF_WIDTH_LANES lanes to either side of its lane's centre. For START_ZONE_S:
# (1) no vehicle or cyclist departs on an edge that starts inside the zone (their departures are
# left out of the episode's demand), and any still waiting to depart there at the ego's entry is
# removed; (2) every vehicle and cyclist in the zone, or close enough behind to reach it in time
# (at the speed limit, or its own speed if faster), has lane changing off (SUMO lane-change mode
# 0), and its own mode back after; one further back cannot reach the zone in that time.
START_ZONE_S = 2.0  # [s]
START_ZONE_HALF_WIDTH_LANES = 2.5  # [lane widths] the ego's lane and two on each side
FRONT_CORRIDOR_HALF_WIDTH_M = 1.75  # [m] "in front of the ego": within half a lane of its axis
FRONT_LOOKAHEAD_M = 30.0  # [m] how far ahead the congestion check looks for a front vehicle
FRONT_HEADING_TOLERANCE_RAD = math.pi / 4  # [rad] a front vehicle heads within this of the ego
STOPPED_SPEED_MPS = 0.1  # [m/s] below this a vehicle counts as stopped
ROUTE_MARGIN_S = 30.0  # [s] demand is drawn for warm-up + timeout + this margin
_SAME_WAY_COS = math.cos(FRONT_HEADING_TOLERANCE_RAD)
_PEDESTRIAN = KIND_CODE["pedestrian"]
_CYCLIST = KIND_CODE["cyclist"]
_VEHICLE = KIND_CODE["vehicle"]


class _Around(NamedTuple):
    """Every participant of a snapshot relative to the ego's centre, computed once a step: the
    sensors, the front-vehicle check and the collision judge all start from these (each used to
    compute them itself; the same operations, so the same numbers)."""

    dx: FloatArray  # [m] x − ego x
    dy: FloatArray  # [m] y − ego y
    distance: FloatArray  # [m] np.hypot(dx, dy)


class World:
    """A scenario's world; :meth:`reset` starts an episode, :meth:`step` advances it by 0.1 s."""

    def __init__(self, config: WorldConfig, *, session: SumoSession | None = None) -> None:
        self.config = config
        self.junction: Junction = read_junction(config.net_file, config.junction_id)
        self.approach: Approach = (self.junction.approach(config.approach) if config.approach
                                   else self.junction.default_approach())
        self.candidates: tuple[CandidatePath, ...] = tuple(
            plan_candidates(self.junction, config.task, approach=self.approach, rho=config.rho))
        self.program = read_program(config.net_file, self.junction.tl_id,
                                    config.signal_start.program_id)
        self.start_lane: Lane = self.junction.lanes[
            config.ego_start.entrance_lane or self.candidates[0].entrance_lane]
        if self.start_lane.id not in {lane.id for lane in self.approach.entrance_lanes}:
            raise ValueError(f"ego.entrance_lane {self.start_lane.id!r} is not an entrance lane of "
                             f"approach {self.approach.id!r}")
        self._link_index = self._signal_link()
        # (phase index, elapsed [s]) of the light at the ego's entry, and where and on which route
        # it enters: public, so that an export of the scene (evaluation/sumo_bundle.py) matches
        self.start_phase = self._signal_phase()
        self.placement = place_ego(self.junction, self.start_lane.id,
                                   config.ego_start.distance_to_stop_line_m, self._route_on())
        self._stop_mid = self.approach.stop_line.mean(axis=0)
        self._forward = np.array([math.cos(self.approach.heading_rad),
                                  math.sin(self.approach.heading_rad)])
        # the judge's point-in-polygon tests, with a memo of the grid cells away from the edges
        self._road = Region(self.junction.drivable_area.buffer(OFF_ROAD_TOLERANCE_M))
        exit_edges = {self.junction.lanes[c.exit_lane].edge_id for c in self.candidates}
        # the target road: the exit lanes' edges and, where an exit edge is a stub, the road on
        # from each candidate's exit lane (its lead-out)
        self._target_exit = Region(unary_union([
            lane.polygon() for lane in self.junction.lanes.values() if lane.edge_id in exit_edges] + [
            LineString(self.junction.lead_out(c.exit_lane).centerline).buffer(
                self.junction.lanes[c.exit_lane].width_m / 2.0, cap_style="flat")
            for c in self.candidates if len(self.junction.lead_out(c.exit_lane).edges) > 1]))
        self._inside = Region(self.junction.polygon)
        self._own_approach = Region(unary_union([lane.polygon() for lane in self.approach.entrance_lanes]))
        self._crossing_areas = tuple(c.polygon for c in self.junction.crossings)  # Observation.crossings
        # lane centre lines by SUMO lane id, internal lanes through the junction included: the
        # turning radius R of f_other comes from the lane a participant is on and where on it
        self.lane_shapes = LaneShapes({lane.id: lane.centerline for lane in self.junction.lanes.values()})
        for a in self.junction.approaches:
            for c in a.connections:
                if c.via_lane and c.via_shape is not None and len(c.via_shape) >= 2:
                    self.lane_shapes[c.via_lane] = c.via_shape
        self._stop_mid_xy: tuple[float, float] = tuple(self._stop_mid.tolist())
        self._collision_sizes: FloatArray | None = None  # the snapshot lengths _collision_reach is for
        self._collision_reach = np.zeros(0)
        self.session = session or SumoSession()
        self._work_dir = Path(tempfile.mkdtemp(prefix="crossroads-world-"))
        self.episode_seed: int | None = None
        self.sumo_driver: SumoDriver | None = None  # set by reset(): SUMO drives the ego
        self.events: list[dict[str, object]] = []  # the world's own events of the episode
        self._clearing_links: dict[str, frozenset[int]] | None = None  # sim/clearing.py, read at the first reset
        self._incoming_lanes: frozenset[str] | None = None  # sim/letting_out.py, read at the first reset
        self._internal_lanes: frozenset[str] | None = None  # the junction's, read at the first reset
        self._ways_from: dict[str, tuple[FloatArray, FloatArray]] = {}  # _way_from's, per internal lane
        self._truth: GroundTruth | None = None  # the true state of the last step (World.truth)

    # --- set-up ----------------------------------------------------------------------------

    def _signal_link(self) -> int:
        """The tl link index of the ego's movement: its start lane into the task's target."""
        return movement_link(self.approach, self.config.task, self.start_lane.id)

    def _signal_phase(self) -> tuple[int, float]:
        """(phase, time spent in it [s]) to start the light in: the scenario's exact phase, or
        where the ego's own link shows the colour asked for (``sim.signals.phase_for_light``)."""
        start = self.config.signal_start
        if start.phase_index is not None:
            offset_for(self.program, 0.0, start.phase_index, start.elapsed_s)  # raises when out of range
            return start.phase_index, start.elapsed_s
        return phase_for_light(self.program, self._link_index, start.ego_light, start.elapsed_s)

    def _route_on(self) -> tuple[str, ...]:
        """The edges the ego's SUMO route takes after its entrance edge: the inner edges of a
        joined junction its movement passes, then the first candidate's exit edge and the road on
        from it (its lead-out: SUMO would take the ego off at the end of a stub exit edge)."""
        target = self.candidates[0].exit_lane
        moves = [c for c in self.approach.connections_for(self.config.task)
                 if c.from_lane == self.start_lane.id]
        move = next((c for c in moves if c.to_lane == target), moves[0] if moves else None)
        inner = move.inner_edges if move is not None else ()
        return (*inner, *self.junction.lead_out(target).edges)

    def _start_pose(self) -> tuple[float, float, float]:
        """Ego centre and heading: ``distance_to_stop_line_m`` of its front bumper before the line,
        along its lane and, where that is short, the road before it (``sim.start``)."""
        p = self.placement
        return p.x, p.y, p.heading_rad

    def reset(self, seed: int, *, sumo_driver: SumoDriver | None = None) -> Observation:
        """Start a fresh episode: SUMO with its warmed-up traffic, then the ego at its start.

        With ``sumo_driver``, SUMO's own driver models drive the ego (policy ``sumo``): advance
        the episode with ``step(None)``. The same seed gives the same traffic either way.
        """
        cfg = self.config
        self.episode_seed = seed
        self.sumo_driver = sumo_driver
        self.events = []
        traffic_seq, sumo_seq, abnormal_seq, noise_seq = np.random.SeedSequence(seed).spawn(4)
        self.demand_plan = self._without_start_zone_departures(
            self.drawn_demand(int(traffic_seq.generate_state(1)[0])))
        routes = write_plan(self.demand_plan, self._work_dir / "traffic.rou.xml")
        self.session.close()
        self.session.start(cfg.net_file, [routes], seed=int(sumo_seq.generate_state(1)[0] % 2**31),
                           step_length_s=SIM_STEP_S)
        self.abnormal = AbnormalTraffic(self.junction, self.approach, cfg.abnormal,
                                        int(abnormal_seq.generate_state(1)[0]))
        self.abnormal.apply_speed_limits(self.session)
        self._noise_rng = np.random.default_rng(noise_seq)
        self._gridlocks = GridlockBreaker(self.junction, cfg.gridlock_stand_s)
        self._clearing = JunctionClearing(self.session, self.program.tl_id, enabled=cfg.junction_clearing,
                                          links=self._clearing_links, exempt=frozenset({EGO_ID}))
        self._clearing_links = self._clearing.links  # the net's: read once, kept for the next reset
        if not cfg.junction_lane_changes:
            self.session.forbid_lane_changes(self._junction_lanes())
        if self._incoming_lanes is None:
            self._incoming_lanes = incoming_lanes(self.session.tl_controlled_links(self.program.tl_id))
        self._letting_out = LettingOut(self._incoming_lanes, enabled=cfg.let_out and cfg.junction_clearing,
                                       exempt=frozenset({EGO_ID}))
        self._courtesy = Courtesy(cfg.standing_ego_courtesy)
        self._look_ahead = LookAhead(EGO_ID, sumo_driver is not None and sumo_driver.look_ahead)
        for _ in range(int(round(cfg.warmup_s / SIM_STEP_S))):
            self.session.step()
            self.abnormal.update(self.session)
            self._gridlocks.update(self.session)
            self._clearing.update(self.session)
            self._letting_out.update(self.session, lambda: self._clearing.inside,
                                     abnormal=self.abnormal.abnormal_ids)
        self.signal_offset_s = apply_start(self.session, self.program, *self.start_phase)
        x, y, heading = self._start_pose()
        self._hold_start_zone(x, y, heading)  # first: _clear_spawn steps SUMO, which inserts
        self._clear_spawn(x, y, heading, cfg.ego_start.speed_mps)
        self.session.add_ego(EGO_ID, list(self.placement.route_edges),
                             depart_lane=self.placement.depart_lane, sumo_driver=sumo_driver)
        speed = cfg.ego_start.speed_mps
        self.ego = np.array([x, y, speed, 0.0, heading, 0.0, 0.0, 0.0])
        self.session.move_ego(EGO_ID, x, y, heading, speed)
        self.session.step()
        if sumo_driver is not None:
            self.session.release_ego(EGO_ID)
        self.time_s = 0.0
        self._sumo_driver_mode = SPEED_MODE_DEFAULT  # SUMO's driver's speed mode (SumoDriver.clear_junction)
        self._sumo_driver_standing_since: float | None = None  # ... standing while clearing, nobody in its way
        self._front_stopped: tuple[str, float] | None = None  # (id, since [s])
        self._stop_line_crossed_s: float | None = None
        self._abnormal_ids = self.abnormal.update(self.session)
        self.outcome: Outcome | None = None
        return self._observe(self.session.snapshot())

    def _clear_spawn(self, x: float, y: float, heading: float, speed: float) -> None:
        """Remove whoever is in the ego's way as it enters, so no episode starts in a crash.

        The cleared box runs along the start lane from behind the ego (SPAWN_CLEARANCE_M, and a
        participant's SPAWN_CLEAR_BEHIND_S of driving more) to as far as the ego covers in
        SPAWN_CLEAR_AHEAD_S at its start speed, across the lane and half of each neighbour.
        """
        snap = self.session.snapshot()
        dx, dy = snap.x - x, snap.y - y
        along = dx * math.cos(heading) + dy * math.sin(heading)
        across = -dx * math.sin(heading) + dy * math.cos(heading)
        ahead = SPAWN_CLEARANCE_M + SPAWN_CLEAR_AHEAD_S * speed
        behind = SPAWN_CLEARANCE_M + SPAWN_CLEAR_BEHIND_S * snap.speed  # per participant: its own headway
        close = (along > -behind) & (along < ahead) & (
            np.abs(across) < self.start_lane.width_m)
        for pid in snap.ids[close]:
            self.session.remove(str(pid))
        if close.any():
            self.session.step()

    def _start_zone_reach_m(self) -> tuple[float, float]:
        """[m] How far the start zone reaches behind and ahead of the ego's centre (START_ZONE_S)."""
        behind = SPAWN_CLEARANCE_M + START_ZONE_S * self.start_lane.speed_limit_mps
        ahead = SPAWN_CLEARANCE_M + SPAWN_CLEAR_AHEAD_S * self.config.ego_start.speed_mps
        return behind, ahead

    def start_zone_edges(self) -> frozenset[str]:
        """The edges of the ego's lead-in that start inside its start zone: a vehicle SUMO
        inserts at the start of one of these appears within START_ZONE_S of the ego."""
        lead = self.junction.lead_in(self.start_lane.id)
        centre = max(0.0, lead.length_m - self.config.ego_start.distance_to_stop_line_m - EGO_LENGTH_M / 2.0)
        behind, ahead = self._start_zone_reach_m()
        return frozenset(edge for edge, start in zip(lead.edges, lead.lane_starts_m)
                         if centre - behind <= start <= centre + ahead)

    def drawn_demand(self, traffic_seed: int) -> DemandPlan:
        """The episode's demand drawn from ``traffic_seed`` (warm-up, timeout and a margin), with
        the scenario's injected over-speeders; :meth:`reset` then holds the start zone clear."""
        cfg = self.config
        plan = build_plan(self.junction, cfg.demand, seed=traffic_seed,
                          duration_s=cfg.warmup_s + cfg.timeout_s + ROUTE_MARGIN_S)
        return with_departures(plan, injected_departures(
            self.junction, self.approach, cfg.abnormal.injection, episode_start_s=cfg.warmup_s,
            limit_mps=cfg.abnormal.limit_outside_mps))

    def _without_start_zone_departures(self, plan: DemandPlan) -> DemandPlan:
        """``plan`` less the vehicles and cyclists that would depart in the start zone while it is
        held: on a :meth:`start_zone_edges` edge from the ego's entry (the end of the warm-up)
        until START_ZONE_S after it (and the steps the entry itself takes). The window opens one
        step before the entry: a departure due within the last warm-up step is not inserted by
        it (nor pending at the entry) but by the step the entry's clearing takes, right beside
        the ego (a car 4.1 m ahead of it, a collision at 0.1 s: DRT's OSM net, seed 1809358627)."""
        edges = self.start_zone_edges()
        begin = self.config.warmup_s - SIM_STEP_S - 1e-9
        end = self.config.warmup_s + START_ZONE_S + 3 * SIM_STEP_S
        kept = tuple(d for d in plan.departures
                     if d.kind == "pedestrian" or d.from_edge not in edges or not begin <= d.depart_s <= end)
        return plan if len(kept) == len(plan.departures) else replace(plan, departures=kept)

    def _hold_start_zone(self, x: float, y: float, heading: float) -> None:
        """Keep the start zone (START_ZONE_S) free as the ego enters at ``x``, ``y``: remove those
        still waiting to depart on its edges, and turn lane changing off for every vehicle and
        cyclist in it or able to reach it in time (each one's own mode is restored by
        :meth:`_release_start_zone`)."""
        edges = self.start_zone_edges()
        waiting = {d.id for d in self.demand_plan.departures if d.from_edge in edges}
        for vid in self.session.pending_vehicle_ids():
            if vid in waiting:
                self.session.remove(vid)
        snap = self.session.snapshot()
        dx, dy = snap.x - x, snap.y - y
        along = dx * math.cos(heading) + dy * math.sin(heading)
        across = -dx * math.sin(heading) + dy * math.cos(heading)
        behind, ahead = self._start_zone_reach_m()
        behind = np.maximum(behind, SPAWN_CLEARANCE_M + START_ZONE_S * snap.speed)
        near = ((along > -behind) & (along < ahead)
                & (np.abs(across) < START_ZONE_HALF_WIDTH_LANES * self.start_lane.width_m)
                & (np.cos(snap.heading - heading) > _SAME_WAY_COS) & (snap.kind_code != _PEDESTRIAN))
        self._start_zone_modes: dict[str, int] = {}
        for vid in map(str, snap.ids[near]):
            self._start_zone_modes[vid] = self.session.lane_change_mode(vid)
            self.session.set_lane_change_mode(vid, 0)

    def _release_start_zone(self) -> None:
        """START_ZONE_S after entry: every vehicle held by :meth:`_hold_start_zone` that is still
        on the road changes lanes as it did before."""
        alive = set(self.session.vehicle_ids)
        for vid, mode in self._start_zone_modes.items():
            if vid in alive:
                self.session.set_lane_change_mode(vid, mode)
        self._start_zone_modes = {}

    # --- the loop --------------------------------------------------------------------------

    def step(self, action: FloatArray | None) -> tuple[Observation, Outcome | None]:
        """Apply ``action`` = [Δδ, Δa] for 0.1 s; returns the new observation and the outcome
        (None while the episode goes on). ``None`` when SUMO drives the ego (``reset`` with a
        ``sumo_driver``): SUMO moves it, and its pose is read back."""
        if self.outcome is not None:
            raise RuntimeError("the episode has ended; call reset(seed) first")
        if (action is None) != (self.sumo_driver is not None):
            raise ValueError("step(None) exactly when SUMO drives the ego (reset with sumo_driver)")
        previous_distance = self._last_distance_m  # of the observation the action answered
        if action is not None:
            self.ego = ego_step(self.ego, np.asarray(action, dtype=np.float64))  # clips the action
            x, y, vx, _, heading = self.ego[:5].tolist()
            self.session.move_ego(EGO_ID, x, y, heading, vx)
        self.session.step()
        if action is None:
            self._read_sumo_ego()
        self._abnormal_ids = self.abnormal.update(self.session)
        self.time_s += SIM_STEP_S
        if self._start_zone_modes and self.time_s >= START_ZONE_S - 1e-9:
            self._release_start_zone()
        self.events.extend(r.to_event(self.time_s) for r in self._gridlocks.update(self.session))
        self._clearing.update(self.session, self._ego_pose())
        self._letting_out.update(self.session, self._caught_inside, abnormal=self._abnormal_ids)
        snap = self.session.snapshot()
        around = self._around(snap)
        obs = self._observe(snap, around)
        self.outcome = self._judge(snap, obs, previous_distance, around)
        if self.outcome is None and self._let_pedestrians_stop(snap, around):
            # a cyclist was taken out: observe again, so no one reads a participant SUMO no longer has
            snap = self.session.snapshot()
            obs = self._observe(snap)
        if self.outcome is None and self._look_ahead.enabled:
            self._look_ahead_for_sumo_driver(snap)
        if self.outcome is None and self.sumo_driver is not None and self.sumo_driver.clear_junction:
            self._let_sumo_driver_clear(obs.light.light)
        return obs, self.outcome

    def _junction_lanes(self) -> frozenset[str]:
        """The internal lanes of the traffic light's links (those after an internal junction
        included); a property of the net, read once."""
        if self._internal_lanes is None:
            links = self._clearing_links or session_movement_links(self.session, self.program.tl_id)
            self._internal_lanes = frozenset(links)
        return self._internal_lanes

    def _caught_inside(self) -> list[str]:
        """Who is inside the junction with its movement's light no longer green: the world's
        caught vehicles (sim/clearing.py) and the ego, whoever drives it (sim/letting_out.py)."""
        inside = list(self._clearing.inside)
        if caught(self.session.vehicle_lane(EGO_ID), self.session.tl_state(self.program.tl_id),
                  self._clearing.links):
            inside.append(EGO_ID)
        return inside

    def _ego_pose(self) -> Pose:
        """The ego as the world's rules read it: (x, y, heading [rad], speed [m/s], length, width)."""
        x, y, speed, _, heading = self.ego[:5].tolist()
        return x, y, heading, speed, EGO_LENGTH_M, EGO_WIDTH_M

    def _let_sumo_driver_clear(self, light: str) -> None:
        """SUMO's driver, inside the junction when its light is no longer green, drives on
        regardless of the junction's right of way (``SumoDriver.clear_junction``), and past the
        foes inside the junction too once it has stood ``SumoDriver.clear_through_after_s`` so
        with no one in its way."""
        clearing = light != "green" and self.session.vehicle_lane(EGO_ID).startswith(":")
        mode = SPEED_MODE_CLEARING if clearing else SPEED_MODE_DEFAULT
        after = self.sumo_driver.clear_through_after_s if self.sumo_driver is not None else None
        if clearing and after is not None:
            standing = float(self.ego[2]) < EGO_STANDING_MPS
            if not standing or self._look_ahead.braking:
                self._sumo_driver_standing_since = None
            elif self._sumo_driver_standing_since is None:
                self._sumo_driver_standing_since = self.time_s
            elif self.time_s - self._sumo_driver_standing_since >= after - 1e-9:
                mode = SPEED_MODE_CLEARING_THROUGH
        else:
            self._sumo_driver_standing_since = None
        if mode != self._sumo_driver_mode:
            self.session.set_speed_mode(EGO_ID, mode)
            self._sumo_driver_mode = mode

    def _look_ahead_for_sumo_driver(self, snap: Snapshot) -> None:
        """SUMO's driver brakes for a pedestrian, cyclist or vehicle in the ego's way
        (sim/look_ahead.py), but, while the ego stands, not for a pedestrian or cyclist the courtesy
        holds (it waits for the ego; once the ego moves, one held still stands in its way) unless
        it stands right in front of the ego, where setting off would touch it (the courtesy lets
        such a one go round the car after a standoff)."""
        is_vehicle = snap.kind_code == _VEHICLE
        rows = (~is_vehicle).nonzero()[0]
        held = self._courtesy.held_pedestrians | set(self._courtesy.held_cyclists)
        if held and float(self.ego[2]) < EGO_STANDING_MPS:
            x, y, heading, _, length, width = self._ego_pose()
            radii = 0.5 * np.maximum(snap.length[rows], snap.width[rows])
            blocking = in_front(x, y, heading, length, width, snap.x[rows], snap.y[rows], radii)
            rows = np.array([r for r, b in zip(rows.tolist(), blocking.tolist(), strict=True)
                             if b or str(snap.ids[r]) not in held], dtype=np.intp)
        cars = is_vehicle.nonzero()[0]
        self._look_ahead.update(self.session, self._ego_pose(),
                                snap.x[rows], snap.y[rows], snap.heading[rows], snap.speed[rows],
                                0.5 * np.maximum(snap.length[rows], snap.width[rows]),
                                vehicles=(snap.x[cars], snap.y[cars], snap.heading[cars], snap.speed[cars],
                                          snap.length[cars], snap.width[cars]),
                                way=self._ego_way_ahead())

    def _ego_way_ahead(self) -> WayAhead | None:
        """The way of SUMO's driver of the ego inside the junction along its lanes
        (sim/look_ahead.py); None outside the junction."""
        lane = self.session.vehicle_lane(EGO_ID)
        if not lane.startswith(":"):
            return None
        points, cum = self._way_from(lane)
        return WayAhead(points, cum, self.session.vehicle_lane_position(EGO_ID))

    def _let_pedestrians_stop(self, snap: Snapshot, around: _Around) -> bool:
        """Pedestrians, cyclists and drivers (not the abnormal ones) about to move into the
        standing ego stop; pedestrians, cyclists and drivers about to move into a moving ego's side
        and drivers following it too (sim/courtesy.py);
        a cyclist taken out after a standoff is an episode event. Whether anyone was taken out."""
        if not self._courtesy.enabled:
            return False
        ego = self._ego_pose()

        def movers(which: np.ndarray) -> Movers:
            rows = which.nonzero()[0]
            return Movers(snap.ids[rows], snap.x[rows], snap.y[rows], snap.heading[rows], snap.speed[rows])

        is_pedestrian, is_cyclist = snap.kind_code == _PEDESTRIAN, snap.kind_code == _CYCLIST
        drivers = (snap.kind_code == _VEHICLE) & (around.distance < COURTESY_NEAR_CAR_M)
        if self._abnormal_ids:
            drivers &= ~np.isin(snap.ids, list(self._abnormal_ids))
        rows = drivers.nonzero()[0]
        cars = Cars(snap.ids[rows], snap.x[rows], snap.y[rows], snap.heading[rows], snap.speed[rows],
                    snap.length[rows], snap.width[rows])
        # a moving ego: the cars the courtesy watches, worked out once for both calls below
        watched = watched_while_moving(cars, ego) if ego[3] >= EGO_STANDING_MPS else None
        if not watched and not self._courtesy.may_act(ego[3]):  # moving, no one held or watched: its sides
            near = ((is_pedestrian & (around.distance < COURTESY_NEAR_M))
                    | (is_cyclist & (around.distance < COURTESY_CYCLIST_NEAR_M)))
            if near.any():  # (most steps: no one)
                self._courtesy.watch_sides(self.session, movers(is_pedestrian & near), ego,
                                           movers(is_cyclist & near))
            return False
        removals = self._courtesy.update(self.session, movers(is_pedestrian), movers(is_cyclist),
                                         ego, cars, self._ways_through_junction(snap, rows, around),
                                         watched=watched)
        self.events.extend(r.to_event(self.time_s) for r in removals)
        return bool(removals)

    def _ways_through_junction(self, snap: Snapshot, rows: np.ndarray, around: _Around) -> dict[str, WayAhead]:
        """The way along their lanes (sim/clearing.py's remaining way, from their lane's start) of
        the cars among ``rows`` of ``snap`` inside the junction within SWEEP_NEAR_M of the ego, for
        the courtesy to follow their bend (sim/courtesy.py's ``sweeping_into``)."""
        near = rows[around.distance[rows] < SWEEP_NEAR_M]
        ways = {}
        for r in near.tolist():
            vid = str(snap.ids[r])
            lane = self.session.vehicle_lane(vid)
            if lane.startswith(":"):
                points, cum = self._way_from(lane)
                ways[vid] = WayAhead(points, cum, self.session.vehicle_lane_position(vid))
        return ways

    def _way_from(self, lane: str) -> tuple[FloatArray, FloatArray]:
        """The way from the start of internal ``lane`` out of the junction, and its arc lengths;
        a property of the net, worked out once per lane."""
        way = self._ways_from.get(lane)
        if way is None:
            points = remaining_way(lane, 0.0, self.session.lane_shape, self.session.lane_next)
            way = self._ways_from[lane] = (points, arc_lengths(points))
        return way

    def _read_sumo_ego(self) -> None:
        """The ego's state from SUMO, which drove it this step (policy ``sumo``)."""
        if not self.session.has_vehicle(EGO_ID):  # SUMO let it arrive before the judge saw it pass
            raise RuntimeError("SUMO's driver left the network before the episode was judged")
        x, y, heading, speed = self.session.vehicle_pose(EGO_ID)
        accel = (speed - float(self.ego[2])) / SIM_STEP_S
        self.ego = np.array([x, y, speed, 0.0, heading, 0.0, 0.0, accel])

    def _around(self, snap: Snapshot) -> _Around:
        """The participants relative to the ego's centre now (see :class:`_Around`)."""
        x, y = self.ego[:2].tolist()
        dx, dy = snap.x - x, snap.y - y
        return _Around(dx, dy, np.hypot(dx, dy))

    def _track_distance(self) -> float:
        """The ego's distance to the stop line now, kept for the next step's crossing check."""
        self._last_distance_m = self._distance_to_stop_line(self.ego)
        return self._last_distance_m

    def _distance_to_stop_line(self, ego: FloatArray) -> float:
        # the front bumper on Python floats (the (2,)-vector arithmetic, element by element), but
        # the dot product still numpy's: it may fuse the multiply-add, Python would not
        x, y, heading = float(ego[0]), float(ego[1]), float(ego[4])
        half = EGO_LENGTH_M / 2.0
        mid_x, mid_y = self._stop_mid_xy
        to_line = np.array([mid_x - (x + half * math.cos(heading)), mid_y - (y + half * math.sin(heading))])
        return float(np.dot(to_line, self._forward))

    def _light(self) -> LightView:
        state = self.session.tl_state(self.program.tl_id)  # read once: the view keeps it for drawing
        at = live_light(self.session, self.program, self._link_index, state=state)
        return LightView(at.light, at.remaining_s, state)

    def _front_vehicle_stopped_s(self, snap: Snapshot, around: _Around) -> float:
        """How long the nearest vehicle ahead of the ego, in its corridor, has been standing
        (SPEC §7 congestion check; 0 when there is none or it moves)."""
        front_id = None
        if len(snap):
            heading = float(self.ego[4])
            c, s = math.cos(heading), math.sin(heading)
            dx, dy = around.dx, around.dy
            ahead = dx * c + dy * s
            lateral = dy * c - dx * s  # = −dx·s + dy·c exactly (negation and + are exact swaps)
            # the corridor first (cheap, few pass), then the kind and heading of those few, one
            # by one on floats (the same tests, fewer numpy calls than on arrays of a few)
            rows = ((ahead > 0) & (ahead < FRONT_LOOKAHEAD_M)
                    & (np.abs(lateral) < FRONT_CORRIDOR_HALF_WIDTH_M)).nonzero()[0]
            row, nearest = -1, math.inf
            for k in rows.tolist():
                # a front vehicle drives the ego's way: oncoming traffic waiting to turn is no queue
                if (snap.kind_code[k] != _PEDESTRIAN
                        and math.cos(float(snap.heading[k]) - heading) > _SAME_WAY_COS
                        and ahead[k] < nearest):  # strictly: the first of equals, as argmin
                    row, nearest = k, ahead[k]
            if row >= 0 and snap.speed[row] < STOPPED_SPEED_MPS:
                front_id = str(snap.ids[row])
        if front_id is None:
            self._front_stopped = None
            return 0.0
        if self._front_stopped is None or self._front_stopped[0] != front_id:
            self._front_stopped = (front_id, self.time_s)
        return self.time_s - self._front_stopped[1]

    def _perceive(self, snap: Snapshot, around: _Around) -> Perceived:
        mask = covered(self.ego[0], self.ego[1], self.ego[4], snap.x, snap.y, DEFAULT_SENSORS,
                       relative=(around.dx, around.dy, around.distance))
        rows = mask.nonzero()[0]  # np.flatnonzero's result, without its Python-level wrappers
        truth = snap.observation_rows[rows]
        kinds = snap.kind[rows]
        observed = (add_noise_unchecked(truth, snap.kind_code[rows], self._noise_rng)
                    if self.config.perception_noise else truth)
        # the map matching: the lane each perceived participant is on (read from SUMO when asked)
        return Perceived(rows, kinds, observed, lanes=lambda indices: snap.lane_id[rows[indices]],
                         kind_codes=snap.kind_code[rows])

    def _observe(self, snap: Snapshot, around: _Around | None = None) -> Observation:
        if around is None:
            around = self._around(snap)
        self._truth = GroundTruth(snap, self._abnormal_ids)
        return Observation(
            time_s=self.time_s,
            ego=self.ego.copy(),
            light=self._light(),
            distance_to_stop_line_m=self._track_distance(),
            front_vehicle_stopped_s=self._front_vehicle_stopped_s(snap, around),
            perceived=self._perceive(snap, around),
            candidates=self.candidates,
            lane_shapes=self.lane_shapes,
            crossings=self._crossing_areas,
        )

    def _collision(self, snap: Snapshot, around: _Around) -> int | None:
        """Row of the first participant whose true footprint overlaps the ego's, if any."""
        if snap.length is not self._collision_sizes:  # the sizes change only when participants do
            self._collision_sizes = snap.length
            self._collision_reach = reject_distance(EGO_LENGTH_M, EGO_WIDTH_M, reach(snap.length, snap.width))
        near = (around.distance <= self._collision_reach).nonzero()[0]  # overlapping's cheap reject
        if len(near) == 0:
            return None
        x, y, _, _, heading = self.ego[:5]
        hits = overlapping((x, y, heading, EGO_LENGTH_M, EGO_WIDTH_M), snap.x[near], snap.y[near],
                           snap.heading[near], snap.length[near], snap.width[near])
        return int(near[hits.argmax()]) if hits.any() else None

    def _judge(self, snap: Snapshot, obs: Observation, previous_distance: float,
               around: _Around) -> Outcome | None:
        """The episode's outcome after this step, judged on the true footprints (None: go on)."""
        x, y, _, _, heading = self.ego[:5].tolist()
        i = self._collision(snap, around)
        if i is not None:
            return Outcome("collision", self.time_s, f"hit {snap.kind[i]} {snap.ids[i]}",
                           str(snap.kind[i]))
        if previous_distance >= 0.0 > obs.distance_to_stop_line_m:
            self._stop_line_crossed_s = self.time_s
            if obs.light.light == "red":
                return Outcome("red_light", self.time_s, "crossed the stop line on red")
        xs, ys = corner_coordinates(x, y, heading, EGO_LENGTH_M, EGO_WIDTH_M)
        if not self._road.contains_all(xs, ys):
            return Outcome("off_road", self.time_s, "left the drivable area")
        if self._stop_line_crossed_s is not None and not self._inside.contains_any(xs, ys):
            if self._target_exit.contains(x, y):
                return Outcome("passed", self.time_s)
            if self._own_approach.contains(x, y):  # just over its line, not yet in the junction
                return self._timeout_or_none(snap, obs)
            # out of the junction, but not onto its task's exit: a wrong exit (judged now, before
            # the ego drives on far from its SUMO route, which SUMO cannot follow)
            return Outcome("off_road", self.time_s, "left the junction by an exit other than its task's")
        return self._timeout_or_none(snap, obs)

    def _timeout_or_none(self, snap: Snapshot, obs: Observation) -> Outcome | None:
        """A timeout once the episode has lasted ``timeout_s`` (with what blocked it), else None."""
        if self.time_s >= self.config.timeout_s - 1e-9:
            detail = f"still driving after {self.config.timeout_s:g} s"
            if obs.front_vehicle_stopped_s > 0.0:  # blocked, not hesitant: say so in the run's record
                detail += f"; the vehicle ahead had stood {obs.front_vehicle_stopped_s:.1f} s"
            blocked = self._blocked_by(snap)
            if blocked is not None:
                detail += (f"; blocked by the world: {blocked.kind} {blocked.participant} stood "
                           f"{blocked.stood_s:.1f} s across every candidate path")
            return Outcome("timeout", self.time_s, detail, blocked_by=blocked)
        return None

    def _blocked_by(self, snap: Snapshot) -> BlockedBy | None:
        """The participant barring every candidate path that has stood the whole episode, if any."""
        bodies = [(k, float(snap.x[k]), float(snap.y[k]), float(snap.width[k]))
                  for k in range(len(snap)) if snap.kind_code[k] != _PEDESTRIAN]
        found = nearest_barrier((float(self.ego[0]), float(self.ego[1])), bodies, self.candidates)
        if found is None:
            return None
        row, ahead = found
        pid = str(snap.ids[row])
        stood = self.session.standing_s(pid)
        if not held_whole_episode(stood, self.time_s):
            return None
        return BlockedBy(pid, str(snap.kind[row]), round(stood, 1), round(ahead, 2))

    @property
    def truth(self) -> GroundTruth:
        """The true state after the last reset or step (the judge's, the trace's; no controller's)."""
        if self._truth is None:
            raise RuntimeError("the world has no state before reset()")
        return self._truth

    @property
    def stop_line_crossed_s(self) -> float | None:
        """[s] since entry at which the ego's front bumper crossed the stop line, if it has."""
        return self._stop_line_crossed_s

    def close(self) -> None:
        self.session.close()
        shutil.rmtree(self._work_dir, ignore_errors=True)

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
