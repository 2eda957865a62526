"""Vehicles caught inside the junction by the end of their green clear it: which lanes belong to
which light, when a vehicle counts as caught, and the rule in SUMO on a scene that jams without it."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import libsumo
import pytest

from crossroads.network.junction import read_junction
from crossroads.network.road import Junction
from crossroads.scenario.spec import load_scenario, to_world_config
import numpy as np

from crossroads.sim.clearing import (
    JunctionClearing,
    caught,
    movement_links,
    remaining_way,
    session_movement_links,
    way_is_clear,
)
from crossroads.sim.gridlock import GridlockBreaker
from crossroads.sim.sumo import SPEED_MODE_CLEARING, SPEED_MODE_CLEARING_THROUGH, SumoSession
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


@contextmanager
def _world_without_ego(tmp_path: Path, intersection: str,
                       plan_s: float) -> Iterator[tuple[SumoSession, Junction, GridlockBreaker]]:
    """SUMO running the traffic of the nominal scenarios on ``intersection`` (seed 20261206, a
    demand plan of ``plan_s``), no ego; with the scenarios' gridlock breaker for the caller to step."""
    cfg = to_world_config(load_scenario(ROOT / f"scenarios/nominal/{intersection}-left.yaml"))
    junction = read_junction(cfg.net_file, cfg.junction_id)
    plan = build_plan(junction, cfg.demand, seed=20261206, duration_s=plan_s)
    routes = write_plan(plan, tmp_path / "r.rou.xml")
    with SumoSession().start(junction.net_file, [routes], seed=20261206) as session:
        yield session, junction, GridlockBreaker(junction, cfg.gridlock_stand_s)


def test_a_session_s_movement_links_reach_a_left_turn_s_part_beyond_its_waiting_point(tmp_path: Path) -> None:
    # e_irregular_oblique's left turns wait at an internal junction: every internal lane a vehicle
    # drives on inside the junction belongs to a link, the parts beyond the waiting points included
    with _world_without_ego(tmp_path, "e_irregular_oblique", 10.0) as (session, junction, _):
        links = session_movement_links(session, junction.tl_id)
        beyond = {nxt for lane in links for nxt in session.lane_successors(lane) if nxt.startswith(":")}
        assert beyond, "the left turns have internal junctions"
        assert beyond <= set(links)


def _first_car_of_the_outer_lane_at_300_s(tmp_path: Path, clearing: bool) -> str:
    """The world of the nominal scenarios on c_three_lane (seed 20261206, a demand plan of 1200 s,
    the gridlock breaker), no ego: where veh184, the first car of the cross street's outer lane
    from 205 s, is at 300 s, 25 s into its green."""
    with _world_without_ego(tmp_path, "c_three_lane", 1200.0) as (session, junction, breaker):
        rule = JunctionClearing(session, junction.tl_id, enabled=clearing)
        while session.time_s < 300.0 - 1e-9:
            session.step()
            breaker.update(session)
            rule.update(session)
            if clearing and rule.cleared:
                vid = next(iter(rule.cleared))
                if vid in session.vehicle_ids:
                    expected = SPEED_MODE_CLEARING_THROUGH if vid in rule.going_first else SPEED_MODE_CLEARING
                    assert libsumo.vehicle.getSpeedMode(vid) == expected
        return session.vehicle_lane("veh184") if "veh184" in session.vehicle_ids else "gone"


@pytest.mark.slow
def test_the_cross_streets_queue_moves_on_its_green_only_with_the_rule(tmp_path: Path) -> None:
    # without it the car stood at its stop line through that green and the next ones (500 s),
    # held by the other axis' left-turners still yielding inside the junction
    assert _first_car_of_the_outer_lane_at_300_s(tmp_path, clearing=False) == "east_in_2"
    assert _first_car_of_the_outer_lane_at_300_s(tmp_path, clearing=True) in ("gone", "west_out_2")


def test_the_remaining_way_runs_from_the_front_through_the_internal_lanes_into_the_exit() -> None:
    shapes = {":C_1_0": np.array([[0.0, 0.0], [10.0, 0.0]]), ":C_9_0": np.array([[10.0, 0.0], [10.0, 4.0]]),
              "out_0": np.array([[10.0, 4.0], [10.0, 104.0]])}
    nexts = {":C_1_0": ":C_9_0", ":C_9_0": "out_0"}
    way = remaining_way(":C_1_0", 6.0, shapes.__getitem__, nexts.get, exit_reach_m=5.0)
    assert way[0].tolist() == [6.0, 0.0] and way[-1].tolist() == [10.0, 9.0]
    assert [10.0, 4.0] in way.tolist()


def _cars(*rows: tuple[float, float, float, float]) -> tuple[np.ndarray, ...]:
    """(x, y, heading, speed) rows as the columns way_is_clear takes, each car 5 m by 2 m."""
    xs, ys, hs, vs = (np.array(c, dtype=float) for c in zip(*rows))
    return xs, ys, hs, vs, np.full(len(rows), 5.0), np.full(len(rows), 2.0)


WAY = np.array([[0.0, 0.0], [20.0, 0.0]])


def test_a_way_is_clear_of_cars_beside_it_and_not_of_one_across_it() -> None:
    assert way_is_clear(WAY, 1.5, *_cars((10.0, 5.0, 0.0, 0.0)))  # alongside, 5 m off
    assert not way_is_clear(WAY, 1.5, *_cars((10.0, 2.0, np.pi / 2, 0.0)))  # its nose 0.5 m off the way
    assert way_is_clear(WAY, 1.5, *_cars((30.0, 0.0, 0.0, 0.0)))  # beyond its end
    assert way_is_clear(WAY, 1.5, *(np.empty(0),) * 6)  # no one


def test_a_way_is_not_clear_of_a_car_that_will_cross_it_within_2_s() -> None:
    coming = (10.0, -12.0, np.pi / 2, 5.0)  # 12 m to the side, driving at the way at 5 m/s
    assert not way_is_clear(WAY, 1.5, *_cars(coming))
    assert way_is_clear(WAY, 1.5, *_cars(coming), times_s=(0.0,))
    leaving = (10.0, -12.0, -np.pi / 2, 5.0)
    assert way_is_clear(WAY, 1.5, *_cars(leaving))


def _when_veh138_enters(tmp_path: Path, through_after_s: float | None) -> float:
    """The world of the nominal scenarios on f_irregular_wide (seed 20261206, a demand plan of
    1000 s, the gridlock breaker), no ego: when veh138, first at the cross street's west_in_3 from
    169 s, leaves that lane."""
    with _world_without_ego(tmp_path, "f_irregular_wide", 1000.0) as (session, junction, breaker):
        rule = JunctionClearing(session, junction.tl_id, through_after_s=through_after_s)
        went_first = 0
        while session.time_s < 400.0:
            session.step()
            rule.update(session)
            breaker.update(session)
            went_first = max(went_first, len(rule.going_first))
            if session.time_s > 170.0 and session.vehicle_lane("veh138") != "west_in_3":
                break
        assert (went_first > 0) is (through_after_s is not None)
        return session.time_s


@pytest.mark.slow
def test_a_knot_of_caught_cars_lets_the_cross_street_go_sooner_when_one_goes_first(tmp_path: Path) -> None:
    # without the second rule, cars of the other axis caught inside the junction stood there
    # 39-75 s waiting on one another, and veh138 waited at its line on green until 305 s
    without = _when_veh138_enters(tmp_path / "without", None)
    with_rule = _when_veh138_enters(tmp_path / "with", 5.0)
    assert without > 300.0
    assert with_rule < without - 15.0
