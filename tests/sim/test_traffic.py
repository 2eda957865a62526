"""Traffic demand: the plan is the seed's, and SUMO runs it at the expected rates."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from crossroads.network import catalogue
from crossroads.network.junction import read_junction
from crossroads.sim.sumo import SumoSession
from crossroads.sim.traffic import TrafficDemand, build_plan, poisson_times, write_routes
from support import COLOGNE1_NET


@pytest.fixture(scope="module")
def three_lane():
    net = catalogue.build("c_three_lane")  # has bike lanes, sidewalks and crossings
    return net, read_junction(net)


def test_poisson_times_rate_and_seed() -> None:
    t = poisson_times(np.random.default_rng(0), 400.0, 36_000.0)
    assert abs(len(t) - 4000) < 4 * math.sqrt(4000)
    assert np.all(np.diff(t) > 0) and t[0] >= 0 and t[-1] < 36_000.0
    assert np.array_equal(t, poisson_times(np.random.default_rng(0), 400.0, 36_000.0))
    assert len(poisson_times(np.random.default_rng(0), 0.0, 100.0)) == 0


def test_plan_is_determined_by_the_seed_and_matches_rates(three_lane) -> None:
    _, j = three_lane
    demand = TrafficDemand()
    a = build_plan(j, demand, seed=11, duration_s=3600)
    assert a == build_plan(j, demand, seed=11, duration_s=3600)
    assert a != build_plan(j, demand, seed=12, duration_s=3600)
    n_lanes = sum(len(ap.entrance_lanes) for ap in j.approaches)
    for kind, rate in (("vehicle", 400), ("cyclist", 100), ("pedestrian", 100)):
        expected = rate * n_lanes
        assert abs(a.count(kind) - expected) < 4 * math.sqrt(expected), kind
    # every entrance lane gets vehicles, only on turns it allows, departing on that lane
    for ap in j.approaches:
        for lane in ap.entrance_lanes:
            mine = [d for d in a.departures if d.kind == "vehicle" and d.from_edge == ap.incoming_edge
                    and d.depart_lane == lane.index]
            assert mine, lane.id
            assert {d.turn for d in mine} <= set(ap.turns_of(lane.id))
    bikes = {b.edge_id: b.index for b in j.bike_lanes}
    assert all(d.depart_lane == bikes[d.from_edge] for d in a.departures if d.kind == "cyclist")
    assert [d.depart_s for d in a.departures] == sorted(d.depart_s for d in a.departures)
    assert min(d.depart_s for d in a.departures) < 5.0  # traffic starts at once


def test_zero_demand_means_none(three_lane) -> None:
    _, j = three_lane
    plan = build_plan(j, TrafficDemand(0.0, 0.0, 50.0), seed=0, duration_s=600)
    assert plan.count("vehicle") == plan.count("cyclist") == 0 and plan.count("pedestrian") > 0
    with pytest.raises(ValueError, match="vehicles_per_hour"):
        TrafficDemand(vehicles_per_hour=-1.0)


def test_sumo_runs_the_demand_on_every_lane_with_cyclists_and_pedestrians(three_lane, tmp_path: Path) -> None:
    net, j = three_lane
    routes = write_routes(j, TrafficDemand(), tmp_path / "d.rou.xml", seed=4, duration_s=200)
    entrance = {ln.id for ap in j.approaches for ln in ap.entrance_lanes}
    crossing_lanes = {f"{c.id}_0" for c in j.crossings}
    bike_lanes = {b.id for b in j.bike_lanes}
    seen_lanes: set[str] = set()
    peds_on_crossings: set[str] = set()
    bikes_on_bike_lanes: set[str] = set()
    departed = {"veh": 0, "bike": 0, "ped": 0}
    with SumoSession().start(net, [routes], seed=4) as sim:
        for _ in range(1200):  # 120 s warm-up
            sim.step()
            for pid in sim.departed_last_step:
                departed[pid.rstrip("0123456789")] += 1
            s = sim.snapshot()
            seen_lanes.update(s.lane_id[s.kind == "vehicle"].tolist())
            peds = s.kind == "pedestrian"
            peds_on_crossings.update(s.ids[peds & np.isin(s.lane_id, list(crossing_lanes))].tolist())
            cyc = s.kind == "cyclist"
            bikes_on_bike_lanes.update(s.ids[cyc & np.isin(s.lane_id, list(bike_lanes))].tolist())
        kinds = set(sim.snapshot().kind)
    assert entrance <= seen_lanes
    assert kinds == {"vehicle", "cyclist", "pedestrian"}
    assert len(peds_on_crossings) >= 10
    assert len(bikes_on_bike_lanes) >= 10
    n = len(entrance)
    # rough rates over 120 s (vehicles may queue before insertion, so only a lower bound is tight)
    assert 0.6 * 400 * n / 30 < departed["veh"] <= 1.3 * 400 * n / 30
    assert 0.5 * 100 * n / 30 < departed["bike"] <= 1.5 * 100 * n / 30
    assert 0.5 * 100 * n / 30 < departed["ped"] <= 1.5 * 100 * n / 30


def test_net_without_pedestrian_infrastructure(tmp_path: Path) -> None:
    j = read_junction(COLOGNE1_NET)
    plan = build_plan(j, TrafficDemand(), seed=0, duration_s=300)
    assert plan.count("pedestrian") == 0 and plan.count("vehicle") > 0
    assert any("no pedestrians" in n for n in plan.notes)
    routes = write_routes(j, TrafficDemand(), tmp_path / "c.rou.xml", seed=0, duration_s=120)
    assert "no pedestrians" in routes.read_text()
    with SumoSession().start(COLOGNE1_NET, [routes], seed=0) as sim:
        sim.step(600)
        s = sim.snapshot()
        assert len(s) > 0 and "pedestrian" not in set(s.kind)
