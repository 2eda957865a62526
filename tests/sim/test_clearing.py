"""Vehicles caught inside the junction by the end of their green clear it: which lanes belong to
which light, when a vehicle counts as caught, and the rule in SUMO on a scene that jams without it."""

from __future__ import annotations

from pathlib import Path

import libsumo
import pytest

from crossroads.network.junction import read_junction
from crossroads.scenario.spec import load_scenario, to_world_config
from crossroads.sim.clearing import JunctionClearing, caught, movement_links
from crossroads.sim.gridlock import GridlockBreaker
from crossroads.sim.sumo import SPEED_MODE_CLEARING, SumoSession
from crossroads.sim.traffic import build_plan, write_plan

ROOT = Path(__file__).resolve().parents[2]


def test_internal_lanes_inherit_their_links_light_across_internal_junctions() -> None:
    controlled = [[("a_0", "b_0", ":C_0_0")], [("a_1", "c_0", ":C_1_0"), ("a_1", "c_1", ":C_1_1")],
                  [("w_0", "x_0", "")]]  # a link without an internal lane adds nothing
    successors = {":C_1_0": (":C_5_0",), ":C_5_0": ("c_0",), ":C_0_0": ("b_0",)}
    links = movement_links(controlled, lambda lane: successors.get(lane, ()))
    assert links == {":C_0_0": frozenset({0}), ":C_1_0": frozenset({1}), ":C_1_1": frozenset({1}),
                     ":C_5_0": frozenset({1})}


@pytest.mark.parametrize(("lane", "state", "expected"), [
    (":C_0_0", "Gr", False),  # its green
    (":C_0_0", "gr", False),  # its green without priority
    (":C_0_0", "yG", True),  # its yellow
    (":C_1_0", "Gr", True),  # its red
    ("a_0", "rr", False),  # not inside the junction
])
def test_caught_once_its_movement_has_no_green(lane: str, state: str, expected: bool) -> None:
    assert caught(lane, state, {":C_0_0": frozenset({0}), ":C_1_0": frozenset({1})}) is expected


def _first_car_of_the_outer_lane_at_300_s(tmp_path: Path, clearing: bool) -> str:
    """The world of the nominal scenarios on c_three_lane (seed 20261206, a demand plan of 1200 s,
    the gridlock breaker), no ego: where veh184, the first car of the cross street's outer lane
    from 205 s, is at 300 s, 25 s into its green."""
    cfg = to_world_config(load_scenario(ROOT / "scenarios/nominal/c_three_lane-left.yaml"))
    junction = read_junction(cfg.net_file, cfg.junction_id)
    plan = build_plan(junction, cfg.demand, seed=20261206, duration_s=1200.0)
    routes = write_plan(plan, tmp_path / "r.rou.xml")
    breaker = GridlockBreaker(junction, cfg.gridlock_stand_s)
    with SumoSession().start(junction.net_file, [routes], seed=20261206) as session:
        rule = JunctionClearing(session, junction.tl_id, enabled=clearing)
        while session.time_s < 300.0 - 1e-9:
            session.step()
            breaker.update(session)
            rule.update(session)
            if clearing and rule.cleared:
                vid = next(iter(rule.cleared))
                if vid in session.vehicle_ids:
                    assert libsumo.vehicle.getSpeedMode(vid) == SPEED_MODE_CLEARING
        return session.vehicle_lane("veh184") if "veh184" in session.vehicle_ids else "gone"


@pytest.mark.slow
def test_the_cross_streets_queue_moves_on_its_green_only_with_the_rule(tmp_path: Path) -> None:
    # without it the car stood at its stop line through that green and the next ones (500 s),
    # held by the other axis' left-turners still yielding inside the junction
    assert _first_car_of_the_outer_lane_at_300_s(tmp_path, clearing=False) == "east_in_2"
    assert _first_car_of_the_outer_lane_at_300_s(tmp_path, clearing=True) in ("gone", "west_out_2")
