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
    junction_lane_sets,
    left_approach,
    opposite_approach,
)
from crossroads.sim.sumo import SumoSession
from crossroads.sim.traffic import TrafficDemand, write_routes

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
