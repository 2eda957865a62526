"""SPEC §8 abnormal traffic, measured in SUMO."""

from __future__ import annotations


import numpy as np
import pytest
from shapely.geometry import LineString, Point

from crossroads.constants import SURROUNDING_LIMIT_INSIDE_MPS, SURROUNDING_LIMIT_OUTSIDE_MPS
from crossroads.intersections import catalogue
from crossroads.network.junction import read_junction
from crossroads.sim.abnormal import (
    AbnormalConfig,
    AbnormalTraffic,
    Injection,
    injected_departures,
    junction_lane_sets,
    left_approach,
    opposite_approach,
    with_departures,
)
from crossroads.sim.config import WorldConfig
from crossroads.sim.sumo import SumoDriver, SumoSession
from crossroads.sim.traffic import NO_TRAFFIC, TrafficDemand, build_plan, write_plan, write_routes
from crossroads.sim.world import World

NET = "b_two_lane"


@pytest.fixture(scope="module")
def scene(tmp_path_factory: pytest.TempPathFactory):
    net = catalogue.build(NET)
    j = read_junction(net)
    routes = write_routes(j, TrafficDemand(pedestrians_per_hour=0.0, cyclists_per_hour=0.0),
                          tmp_path_factory.mktemp("ab") / "r.rou.xml", seed=8, duration_s=200)
    return net, j, routes


def test_opposite_and_left(scene) -> None:
    _, j, _ = scene
    ego = j.default_approach()
    assert opposite_approach(j, ego).incoming_edge == "north_in"
    assert left_approach(j, ego).incoming_edge == "west_in"


def _run(scene, cfg: AbnormalConfig, seed: int, steps: int):
    net, j, routes = scene
    ab = AbnormalTraffic(j, j.default_approach(), cfg, seed=seed)
    speeds: dict[str, float] = {}
    tracks: dict[str, list[tuple[str, float, float]]] = {}
    ever: dict[str, str] = {}
    with SumoSession().start(net, [routes], seed=seed) as sim:
        n_in, n_out = ab.apply_speed_limits(sim)
        inside, outside = junction_lane_sets(j, sim.lane_ids())
        assert n_in > 0 and n_out > 0
        assert all(sim.lane_max_speed(ln) == SURROUNDING_LIMIT_INSIDE_MPS for ln in inside)
        assert all(sim.lane_max_speed(ln) == SURROUNDING_LIMIT_OUTSIDE_MPS for ln in outside)
        for _ in range(steps):
            sim.step()
            ab.update(sim)
            ever.update(ab.kinds)
            s = sim.snapshot()
            for i, vid in enumerate(s.ids.tolist()):
                speeds[vid] = max(speeds.get(vid, 0.0), float(s.speed[i]))
                if s.lane_id[i].startswith(":"):
                    tracks.setdefault(vid, []).append((s.lane_id[i], float(s.x[i]), float(s.y[i])))
        # keep the junction tracks of vehicles that got through it (not of those still inside)
        still_inside = {v for v, ln in zip(s.ids.tolist(), s.lane_id.tolist()) if ln.startswith(":")}
    return ever, speeds, {v: t for v, t in tracks.items() if v not in still_inside}


def test_overspeed_vehicles_exceed_the_limit_and_others_do_not(scene) -> None:
    _, j, _ = scene
    ever, speeds, _ = _run(scene, AbnormalConfig.overspeed(0.5, share=1.0), seed=3, steps=1500)
    fast = [v for v, k in ever.items() if k == "overspeed"]
    assert len(fast) >= 3
    limit = SURROUNDING_LIMIT_OUTSIDE_MPS
    assert max(speeds[v] for v in fast) >= 1.4 * limit
    normal = [v for v in speeds if v not in ever]
    assert normal and max(speeds[v] for v in normal) <= limit + 1e-6


def test_overspeed_share_is_seeded(scene) -> None:
    cfg = AbnormalConfig.overspeed(0.2, share=0.5)
    a, _, _ = _run(scene, cfg, seed=5, steps=600)
    b, _, _ = _run(scene, cfg, seed=5, steps=600)
    assert a == b and 0 < len(a)


def test_rounding_vehicles_leave_their_connection_inside_the_junction(scene) -> None:
    _, j, _ = scene
    ever, _, tracks = _run(scene, AbnormalConfig.rounding(1.0), seed=2, steps=1500)
    # Each connection's whole path: entrance lane + SUMO's internal path + exit lane, because a
    # centre half a length behind the front is still on the lanes before and after.
    vias: dict[str, list[LineString]] = {}
    for a in j.approaches:
        for c in a.connections:
            if c.via_lane and c.via_shape is not None and c.to_lane in j.lanes:
                vias.setdefault(c.via_lane.rsplit("_", 1)[0], []).append(LineString(np.vstack([
                    j.lanes[c.from_lane].centerline, c.via_shape, j.lanes[c.to_lane].centerline])))

    def off(vid: str) -> float:
        # Distance of the centre from the connection paths of the internal edge the vehicle
        # entered on (SUMO may change lanes on a multi-lane internal edge).
        paths = vias.get(tracks[vid][0][0].rsplit("_", 1)[0], [])
        if not paths:
            return 0.0
        return max(min(p.distance(Point(x, y)) for p in paths) for _, x, y in tracks[vid])

    rounding = [v for v, k in ever.items() if k == "rounding" and v in tracks]
    assert len(rounding) >= 2
    assert all(off(v) > 1.0 for v in rounding), [(v, off(v)) for v in rounding if off(v) <= 1.0]
    normal = [v for v in tracks if v not in ever and tracks[v][0][0].rsplit("_", 1)[0] in vias]
    # normal vehicles follow their connection: only the centre-vs-front-on-a-curve sag remains
    worst = max(normal, key=off)
    assert normal and off(worst) < 0.6, (worst, off(worst))


def test_injected_over_speeders_are_timed_on_the_opposite_innermost_straight_lane(scene) -> None:
    _, j, _ = scene
    ego = j.default_approach()
    opp = opposite_approach(j, ego)
    injection = Injection(count=3, arrive_s=12.0, excess=0.5, headway_s=2.5)
    deps = injected_departures(j, ego, injection, episode_start_s=30.0, limit_mps=SURROUNDING_LIMIT_OUTSIDE_MPS)
    straight = [ln for ln in opp.entrance_lanes if ln.id in {c.from_lane for c in opp.connections_for("straight")}]
    lane = max(straight, key=lambda ln: ln.index)
    lead = lane.length_m / (SURROUNDING_LIMIT_OUTSIDE_MPS * 1.5)
    assert [d.id for d in deps] == ["inj0", "inj1", "inj2"]
    assert all(d.from_edge == opp.incoming_edge and d.depart_lane == lane.index and d.turn == "straight"
               and d.speed_factor == 1.5 for d in deps)
    assert [d.depart_s for d in deps] == pytest.approx([30.0 + 12.0 + 2.5 * k - lead for k in range(3)], abs=0.01)
    assert injected_departures(j, ego, None, episode_start_s=30.0, limit_mps=8.33) == ()
    assert injected_departures(j, ego, Injection(count=0), episode_start_s=30.0, limit_mps=8.33) == ()
    early = injected_departures(j, ego, Injection(arrive_s=0.0), episode_start_s=0.0, limit_mps=8.33)
    assert early[0].depart_s == 0.0  # due before its lane allows: it departs at once, late

    plan = build_plan(j, TrafficDemand(), seed=4, duration_s=120.0)
    merged = with_departures(plan, deps)
    times = [d.depart_s for d in merged.departures]
    assert times == sorted(times) and len(merged.departures) == len(plan.departures) + 3
    assert [d for d in merged.departures if not d.id.startswith("inj")] == list(plan.departures)


def test_the_route_file_gives_an_injected_vehicle_its_own_speed_factor(scene, tmp_path) -> None:
    _, j, _ = scene
    deps = injected_departures(j, j.default_approach(), Injection(arrive_s=5.0, excess=0.2),
                               episode_start_s=20.0, limit_mps=SURROUNDING_LIMIT_OUTSIDE_MPS)
    text = write_plan(with_departures(build_plan(j, NO_TRAFFIC, seed=1, duration_s=60.0), deps),
                      tmp_path / "r.rou.xml").read_text()
    assert '<trip id="inj0"' in text and 'speedFactor="1.2000"' in text


def test_an_injected_over_speeder_reaches_the_opposite_line_when_due() -> None:
    """On an empty road: due 10 s after the start at +50 %, it crosses the opposite stop line
    within half a second of that, above any ordinary car's speed, named an over-speeder, and the drawn
    traffic of a scenario with the injection is the one without it."""
    net = catalogue.build("c_three_lane")
    cfg = WorldConfig(net_file=net, task="left", warmup_s=20.0, timeout_s=30.0, demand=NO_TRAFFIC,
                      abnormal=AbnormalConfig(injection=Injection(arrive_s=10.0, excess=0.5)))
    with World(cfg) as world:
        world.reset(3, sumo_driver=SumoDriver(max_speed_mps=8.33))  # it yields to the over-speeder
        opp = opposite_approach(world.junction, world.approach)
        line = LineString(opp.stop_line)
        start = world.session.time_s
        crossed = None
        kinds: set[str] = set()
        previous = None
        for _ in range(200):
            _, outcome = world.step(None)
            if outcome is not None:
                break
            snap = world.session.snapshot()
            ids = snap.ids.tolist()
            if "inj0" in ids:
                kinds.add(world.abnormal.kinds.get("inj0", ""))
                i = ids.index("inj0")
                here = Point(float(snap.x[i]), float(snap.y[i]))
                if previous is not None and crossed is None and LineString([previous, here]).intersects(line):
                    crossed = (world.session.time_s - start, float(snap.speed[i]))
                previous = here
        assert crossed is not None, "the injected vehicle never crossed the opposite stop line"
        assert crossed[0] == pytest.approx(10.0, abs=0.5)
        # slowing for the junction's own limit (×1.5 too), faster than any ordinary car there
        assert crossed[1] >= 1.5 * SURROUNDING_LIMIT_INSIDE_MPS - 0.2 > SURROUNDING_LIMIT_OUTSIDE_MPS
        assert kinds == {"overspeed"}
    plans = []
    for abnormal in (AbnormalConfig(), AbnormalConfig(injection=Injection(arrive_s=10.0))):
        with World(WorldConfig(net_file=net, task="left", warmup_s=20.0, timeout_s=30.0,
                               abnormal=abnormal)) as world:  # libsumo: one at a time
            world.reset(8)
            plans.append(world.demand_plan.departures)
    assert [d for d in plans[1] if not d.id.startswith("inj")] == list(plans[0])
    assert len(plans[1]) == len(plans[0]) + 1
