"""Per-lane flow: which link a lane's green is read from, the window's rates, and in SUMO a light
scene that flows as scheduled against a dense one whose left-turn lanes leave queues behind."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from crossroads.intersections import catalogue
from crossroads.network.junction import read_junction
from crossroads.sim.flow import measure_flow
from crossroads.sim.lane_flow import LaneFlow, lane_flows, main_link_indices
from crossroads.sim.traffic import TrafficDemand


def test_a_lanes_green_is_its_straight_movements_where_it_has_one() -> None:
    junction = read_junction(catalogue.build("c_three_lane"))
    links = main_link_indices(junction)
    for approach in junction.approaches:
        for lane in approach.entrance_lanes:
            conns = [c for c in approach.connections if c.from_lane == lane.id]
            turns = {c.turn for c in conns}
            expected = {c.tl_link_index for c in conns if "straight" not in turns or c.turn == "straight"}
            assert set(links[lane.id]) == expected and expected


def test_rates_per_hour_and_unknown_demand_is_nan() -> None:
    (known, unknown) = lane_flows(
        [("a_0", ("straight",)), ("b_0", ("left",))], window_s=1800.0,
        demand={"a_0": 100, "b_0": 7}, known_demand=frozenset({"a_0"}), crossed={"a_0": 90, "b_0": 5},
        green_s={"a_0": 900.0}, queued_green_s={"a_0": 360.0}, crossed_queued={"a_0": 60},
        greens={"a_0": 10, "b_0": 10}, greens_queued={"a_0": 3})
    assert known.demand_h == 200.0 and known.crossed_h == 180.0 and known.ratio == pytest.approx(0.9)
    assert known.green_share == 0.5 and known.queued_discharge_h == 600.0
    assert known.oversaturated_share == pytest.approx(0.3)
    assert math.isnan(unknown.demand_h) and math.isnan(unknown.ratio)
    assert math.isnan(unknown.queued_discharge_h)  # never queued on its green
    assert unknown.oversaturated_share == 0.0
    assert math.isnan(LaneFlow("c_0", (), 0.0, 0.0, 0.0, math.nan, 0, 0).oversaturated_share)


def _lanes(tmp_path: Path, vehicles_per_hour: float) -> tuple[LaneFlow, ...]:
    junction = read_junction(catalogue.build("c_three_lane"))
    demand = TrafficDemand(vehicles_per_hour=vehicles_per_hour, cyclists_per_hour=0.0, pedestrians_per_hour=100.0)
    report = measure_flow(junction, demand, tmp_path, seed=3, warmup_s=120.0, window_s=600.0,
                          gridlock_stand_s=75.0, per_lane=True)
    assert len(report.lanes) == report.entrance_lanes
    return report.lanes


def test_light_traffic_leaves_no_queue_and_dense_left_turns_do(tmp_path: Path) -> None:
    light = _lanes(tmp_path / "light", 100.0)
    # every lane's green came and went (a 103 s cycle: 5 or 6 greens in 600 s) and left no queue
    assert all(5 <= f.greens <= 6 for f in light)
    assert sum(f.greens_ending_queued for f in light) <= 1
    demanded = sum(f.demand_h for f in light)
    assert sum(f.crossed_h for f in light) == pytest.approx(demanded, rel=0.1)
    dense = _lanes(tmp_path / "dense", 400.0)
    left = [f for f in dense if f.turns == ("left",)]
    straight = [f for f in dense if f.turns == ("straight",)]
    assert left and straight
    # permissive left turns against 1 200 oncoming vehicles an hour: most greens leave a queue,
    # and the left lanes serve less than they are given; the straight-only lanes clear
    assert sum(f.greens_ending_queued for f in left) > sum(f.greens for f in left) / 2
    assert sum(f.crossed_h for f in left) < 0.9 * sum(f.demand_h for f in left)
    assert sum(f.greens_ending_queued for f in straight) <= 1
