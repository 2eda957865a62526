"""Policy ``sumo``: SUMO's own driver drives the ego, judged by the world's judge like any policy."""

from __future__ import annotations

import libsumo
import pytest

from crossroads.evaluation.episode import run_episode
from crossroads.evaluation.sumo_driver import SumoDriverPolicy
from crossroads.intersections import catalogue
from crossroads.sim.config import WorldConfig
from crossroads.sim.traffic import NO_TRAFFIC, TrafficDemand
from crossroads.sim.world import EGO_ID, World
from support import patched_episode


@pytest.fixture(scope="module")
def net():
    return catalogue.build("c_three_lane")


def test_sumo_driver_passes_an_empty_junction(net) -> None:
    config = WorldConfig(net_file=net, task="left", demand=NO_TRAFFIC, warmup_s=0.0, timeout_s=60.0)
    with World(config) as world:
        result = run_episode(world, SumoDriverPolicy(), seed=4)
    assert result.outcome == "passed"
    assert result.travel_time_s is not None and 2.0 < result.travel_time_s < 15.0
    assert result.blocked_by is None


def test_sumo_driver_is_seeded(net) -> None:
    config = WorldConfig(net_file=net, task="straight", demand=TrafficDemand(), warmup_s=30.0,
                         timeout_s=40.0)
    with World(config) as world:
        first = run_episode(world, SumoDriverPolicy(), seed=9)
        again = run_episode(world, SumoDriverPolicy(), seed=9)
    assert first == again


def test_a_collision_with_sumos_ego_is_judged_on_the_true_footprints(net) -> None:
    config = WorldConfig(net_file=net, task="left", demand=NO_TRAFFIC, warmup_s=0.0, timeout_s=30.0)
    with World(config) as world:
        world.reset(7, sumo_driver=SumoDriverPolicy().driver)
        exit_edge = world.junction.lanes[world.candidates[0].exit_lane].edge_id
        libsumo.route.add("intruder_route", [world.approach.incoming_edge, exit_edge])
        libsumo.vehicle.add("intruder", "intruder_route", typeID="car", depart="now", departLane="best")
        _, outcome = world.step(None)  # the intruder enters the network
        assert outcome is None
        x, y, heading, _ = world.session.vehicle_pose(EGO_ID)
        world.session.set_speed("intruder", 0.0)
        world.session.move_vehicle("intruder", x + 1.0, y, heading)  # onto the ego's footprint
        _, outcome = world.step(None)
    assert outcome is not None and outcome.kind == "collision"
    assert outcome.detail == "hit vehicle intruder" and outcome.other_kind == "vehicle"


def test_step_refuses_a_mix_of_drivers(net) -> None:
    config = WorldConfig(net_file=net, task="left", demand=NO_TRAFFIC, warmup_s=0.0, timeout_s=5.0)
    with World(config) as world:
        world.reset(1)
        with pytest.raises(ValueError, match="SUMO drives"):
            world.step(None)


@pytest.mark.slow
@pytest.mark.parametrize(("scenario", "seed", "hit"), [
    ("e_irregular_oblique-left", "808738376", "hit pedestrian"),
    ("a_single_lane-straight", "179128172", "hit vehicle"),
    # turning right into a left-turner standing over its bend, which the straight corridor misses
    ("d_irregular_skewed-right", "1109794873", "hit vehicle"),
])
def test_sumo_driver_brakes_for_whoever_is_in_its_way_ahead(scenario: str, seed: str, hit: str) -> None:
    """Runs of benchmarks/world_flow.py's base seed where SUMO's driver, without the look-ahead
    (sim/look_ahead.py), collides, and with it waits and passes: on the nominal left turn of
    e_irregular_oblique, inside the junction past its crossing's link, it drives into a pedestrian
    walking in front of it; going straight on a_single_lane it stops at its line against the rear
    corner of a left-turner waiting just inside the junction; turning right on d_irregular_skewed
    it drives into the side of the opposite left-turner standing over its bend, where the two merge
    into one exit lane (the look-ahead places the ego's body along its way). Each episode runs first in a fresh
    process, as ``crossroads run`` does: SUMO's result can depend on what the process ran before (a
    batch forks each episode for that reason). (A change of the world's traffic may move the
    others: then find another such run with the benchmark, ``--policy sumo --scenario ...``.)"""
    outcomes = {mode: patched_episode(scenario, "sumo", int(seed), driver={"look_ahead": mode == "on"})
                for mode in ("off", "on")}
    assert outcomes["off"][0] == "collision" and outcomes["off"][1].startswith(hit), outcomes
    assert outcomes["on"][0] == "passed", outcomes


def _patched_episode(scenario: str, seed: int, *patches: str) -> list:
    """SUMO's driver on one nominal scenario in a fresh process, with ``patches`` (support.py)."""
    return patched_episode(scenario, "sumo", seed, *patches)


@pytest.mark.slow
def test_the_cross_street_waits_for_a_caught_ego_that_sets_off_after_the_let_outs_bound() -> None:
    """e_irregular_oblique's nominal left turn, run 1848100215 of benchmarks/world_flow.py's base
    seed: SUMO's driver stands caught at its waiting point 21 s behind the oncoming traffic clearing
    the junction; the let-out's bound let the cross street go just as it set off, and the cross
    street's first car drove into its side, until a caught vehicle that moves was let out however
    long it had been caught (sim/letting_out.py)."""
    before = _patched_episode("e_irregular_oblique-left", 1848100215, "crossroads.sim.letting_out:MOVING_MPS=math.inf",
                              "crossroads.sim.world:SPEED_MODE_CLEARING_THROUGH=23")  # as SUMO's driver cleared then
    assert before[:2] == ["collision", "hit vehicle veh11"], before
    assert _patched_episode("e_irregular_oblique-left", 1848100215)[0] == "passed"


@pytest.mark.slow
def test_a_pedestrian_held_in_front_of_sumos_driver_goes_round_it() -> None:
    """c_three_lane's nominal left turn, run 1416578486 of benchmarks/world_flow.py's base seed:
    a pedestrian crossing the ego's exit is held 0.5 m in front of its bumper, its way grazing the
    front corner; SUMO's driver, going first past the pedestrians the courtesy holds, crept into it.
    Now it waits for one right in front of it, and the pedestrian goes round the car after the
    standoff (sim/courtesy.py)."""
    before = _patched_episode("c_three_lane-left", 1416578486,
                              "crossroads.sim.world:in_front=lambda *a: np.zeros(len(a[5]), dtype=bool)",
                              "crossroads.sim.courtesy:PEDESTRIAN_STANDOFF_S=math.inf")
    assert before[:2] == ["collision", "hit pedestrian ped34"], before
    outcome, _, events = _patched_episode("c_three_lane-left", 1416578486)
    assert outcome == "passed" and "gridlock_removed" in events


@pytest.mark.slow
def test_sumo_driver_clears_the_junction_once_its_light_is_no_longer_green() -> None:
    """The nominal left turn of c_three_lane, run 2016976523 of benchmarks/world_flow.py's base
    seed: without clearing, SUMO's driver times out (still driving after 206 s); with it, it
    passes. In the world before drivers let those caught inside the junction out (``let_out``),
    which lets this run out either way. Fresh processes, as above."""
    outcomes = {mode: patched_episode("c_three_lane-left", "sumo", 2016976523, world={"let_out": False},
                                      driver={"clear_junction": mode == "on"})
                for mode in ("off", "on")}
    assert outcomes["off"][0] == "timeout", outcomes
    assert outcomes["on"][0] == "passed", outcomes


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "car"), [(1771952177, "veh52"), (1272930509, "veh43")])
def test_a_car_two_rules_hold_for_the_ego_stays_held_when_one_lets_go(seed: int, car: str) -> None:
    """b_two_lane's nominal left turn, runs of benchmarks/world_flow.py's base seed: SUMO's driver
    clears the junction at the end of its green into the exit a right-turner, standing inside the
    junction, merges into too. The letting out held the right-turner while the ego moved, the
    courtesy while it stood, and each, letting go, released the other's hold: the right-turner
    drove into the ego's side. Now a vehicle stands until every rule holding it has let go
    (SumoSession.hold_vehicle); the two rules sharing one name behave as before."""
    before = _patched_episode("b_two_lane-left", seed, "crossroads.sim.letting_out:HOLDER='courtesy'")
    assert before[:2] == ["collision", f"hit vehicle {car}"], before
    assert _patched_episode("b_two_lane-left", seed)[0] == "passed"


@pytest.mark.slow
def test_sumos_driver_standing_caught_with_no_one_in_its_way_clears_past_those_inside() -> None:
    """e_irregular_oblique's nominal left turn, run 1696336797 of benchmarks/world_flow.py's base
    seed: SUMO's driver stands at its left turn's waiting point through its whole second green (no
    gap it accepts in three oncoming lanes) and then, clearing the junction in SUMO's speed mode that
    still yields to the foes it counts inside the junction, stood on with no one in its way to the
    timeout. Once it has stood 5 s so it clears past them too (SumoDriver.clear_through_after_s)."""
    before = _patched_episode("e_irregular_oblique-left", 1696336797,
                              "crossroads.sim.world:SPEED_MODE_CLEARING_THROUGH=23")  # never past them
    assert before[0] == "timeout", before
    assert _patched_episode("e_irregular_oblique-left", 1696336797)[0] == "passed"
