"""Traffic demand: the plan is the seed's, and SUMO runs it at the expected rates."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from crossroads.intersections import catalogue
from crossroads.network.junction import read_junction
from crossroads.sim.sumo import SumoSession
from crossroads.sim.traffic import (
    TrafficDemand,
    build_plan,
    lane_split,
    poisson_times,
    walkable_pairs,
    write_plan,
    write_routes,
)
from support import COLOGNE1_NET, sumo_example


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


def test_turn_shares_split_an_approach_and_level_its_lanes(three_lane) -> None:
    _, j = three_lane
    south = j.approach("south_in")  # lanes: right+straight, straight, left
    split = lane_split(south, {"left": 120.0, "straight": 840.0, "right": 240.0})
    assert split["left"] == {4: 120.0} and split["right"] == {2: 240.0}
    assert split["straight"] == {2: 300.0, 3: 540.0}  # both straight lanes end at 540 veh/h
    plan = build_plan(j, TrafficDemand(turn_shares=(0.1, 0.7, 0.2)), seed=3, duration_s=36_000)
    mine = [d for d in plan.departures if d.kind == "vehicle" and d.from_edge == "south_in"]
    shares = {t: sum(d.turn == t for d in mine) / len(mine) for t in ("left", "straight", "right")}
    assert shares == pytest.approx({"left": 0.1, "straight": 0.7, "right": 0.2}, abs=0.02)
    assert len(mine) == pytest.approx(400 * 3 * 10, rel=0.05)  # per entrance lane × lanes × 10 h
    assert all(d.turn in south.turns_of(f"south_in_{d.depart_lane}") for d in mine)
    per_lane = build_plan(j, TrafficDemand(turn_shares=None), seed=3, duration_s=3600)
    left_lane = [d for d in per_lane.departures if d.from_edge == "south_in" and d.depart_lane == 4
                 and d.kind == "vehicle"]
    assert {d.turn for d in left_lane} == {"left"} and len(left_lane) == pytest.approx(400, rel=0.2)
    with pytest.raises(ValueError, match="turn_shares"):
        TrafficDemand(turn_shares=(0.0, 0.0, 0.0))


def test_cyclists_ride_straight_or_right_unless_asked_and_only_where_bicycles_may(three_lane) -> None:
    _, j = three_lane
    plan = build_plan(j, TrafficDemand(), seed=5, duration_s=3600)
    bikes = [d for d in plan.departures if d.kind == "cyclist"]
    assert bikes and {d.turn for d in bikes} == {"straight", "right"}
    with_left = build_plan(j, TrafficDemand(cyclist_left_turns=True), seed=5, duration_s=3600)
    assert "left" in {d.turn for d in with_left.departures if d.kind == "cyclist"}
    # a leg none of whose lanes admits bicycles gets no cyclists, and the plan says so
    south = j.approach("south_in")
    car_only = replace(south, entrance_lanes=tuple(replace(ln, allowed_classes=frozenset({"passenger"}))
                                                   for ln in south.entrance_lanes))
    no_bike_lanes = replace(j, approaches=tuple(car_only if a is south else a for a in j.approaches),
                            bike_lanes=tuple(b for b in j.bike_lanes if b.edge_id != "south_in"))
    plan = build_plan(no_bike_lanes, TrafficDemand(), seed=5, duration_s=3600)
    assert not [d for d in plan.departures if d.kind == "cyclist" and d.from_edge == "south_in"]
    assert any("no cyclists from 'south_in'" in n for n in plan.notes)


def test_pedestrians_walk_only_between_sidewalks_the_junction_joins(tmp_path: Path) -> None:
    """Ingolstadt's node 335525545 (in the eclipse-sumo wheel): its one crossing joins the sidewalks
    of three legs, a walking area of its own those of the fourth leg's two edges, and nothing joins
    the two groups; SUMO refuses a walk between them ("No connection found"). The plan draws walks
    within a group only, and SUMO departs every one of them."""
    net = sumo_example("tools/game/fkk_in/ingolstadt.net.xml.gz")
    j = read_junction(net, "335525545")
    legs = {a.incoming_edge: a.outgoing_edge for a in j.approaches}
    assert legs == {"29119849#1": "248012815", "116687469#0": "29119850", "gneE9": "-gneE9"}
    reach = walkable_pairs(j, list(legs), list(legs.values()))
    assert reach == {"29119849#1": ["29119850"], "116687469#0": ["248012815", "-gneE9"],
                     "gneE9": ["248012815", "-gneE9"]}
    plan = build_plan(j, TrafficDemand(vehicles_per_hour=0.0, cyclists_per_hour=0.0), seed=2, duration_s=600)
    walks = {(d.from_edge, d.to_edge) for d in plan.departures if d.kind == "pedestrian"}
    assert walks == {("29119849#1", "29119850"), ("116687469#0", "248012815"), ("116687469#0", "-gneE9"),
                     ("gneE9", "248012815")}  # never back to the own leg, never across the gap
    assert not any("pedestrians" in n for n in plan.notes)  # every leg got some
    routes = write_plan(replace(plan, departures=plan.departures[:8]), tmp_path / "p.rou.xml")
    with SumoSession().start(net, [routes], seed=2) as sim:  # a walk SUMO cannot route fails here
        departed = 0
        for _ in range(int(plan.departures[7].depart_s * 10) + 10):
            sim.step()
            departed += sum(pid.startswith("ped") for pid in sim.departed_last_step)
        assert departed == 8
    # a leg whose sidewalk reaches no other leg's gets none, and the plan names it once
    without = replace(j, approaches=tuple(a for a in j.approaches if a.incoming_edge != "116687469#0"))
    plan = build_plan(without, TrafficDemand(vehicles_per_hour=0.0, cyclists_per_hour=0.0), seed=2,
                      duration_s=600)
    assert {d.from_edge for d in plan.departures} == {"gneE9"}
    assert [n for n in plan.notes if "pedestrians" in n] == [
        "no pedestrians from '29119849#1': the walking areas and crossings of junction '335525545' "
        "join its sidewalk to no other leg's"]
