"""Flow measurement on a scene with known demand: what is scheduled crosses, per lane and hour."""

from __future__ import annotations

from pathlib import Path

import pytest

from crossroads.intersections import catalogue
from crossroads.network.junction import read_junction
from crossroads.sim.flow import KindFlow, measure_flow
from crossroads.sim.traffic import TrafficDemand


def test_light_traffic_crosses_as_scheduled(tmp_path: Path) -> None:
    junction = read_junction(catalogue.build("b_two_lane"))
    demand = TrafficDemand(vehicles_per_hour=150.0, cyclists_per_hour=0.0, pedestrians_per_hour=60.0)
    report = measure_flow(junction, demand, tmp_path, seed=5, warmup_s=120.0, window_s=600.0,
                          gridlock_stand_s=60.0)
    assert report.entrance_lanes == sum(len(a.entrance_lanes) for a in junction.approaches)
    vehicles, cyclists, pedestrians = (report.of(k) for k in ("vehicle", "cyclist", "pedestrian"))
    # the scheduled departures are the demand (a Poisson count: within 25 % over 600 s)
    assert vehicles.demand_per_lane_h == pytest.approx(150.0, rel=0.25)
    assert pedestrians.demand_per_lane_h == pytest.approx(60.0, rel=0.35)
    # light traffic: what departs in the window crosses (give or take those still on the way)
    assert vehicles.ratio == pytest.approx(1.0, abs=0.1)
    assert pedestrians.ratio == pytest.approx(1.0, abs=0.2)
    assert cyclists.demand_per_lane_h == 0.0 and cyclists.crossed_per_lane_h == 0.0
    crossed = vehicles.crossed_per_lane_h * report.entrance_lanes * report.window_s / 3600.0
    assert vehicles.removed <= 0.02 * crossed  # the gridlock breaker: rare in light traffic


def test_ratio_without_demand_is_nan() -> None:
    assert KindFlow("cyclist", 0.0, 0.0, 0).ratio != KindFlow("cyclist", 0.0, 0.0, 0).ratio
