"""Drivers let those caught inside the junction out before they enter on green: the geometry, and
the rule in SUMO on a scene where SUMO's driver of the ego stays caught at its waiting point
without it."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from crossroads.evaluation.sumo_driver import SumoDriverPolicy
from crossroads.scenario.spec import load_scenario, to_world_config
from crossroads.sim import letting_out
from crossroads.sim.letting_out import (
    LET_OUT_FOR_S,
    can_stop_before,
    distance_to_meeting,
    incoming_lanes,
    way_through,
    ways_meet,
)
from crossroads.sim.clearing import CHECK_EVERY_S
from crossroads.sim.world import EGO_ID, World

ROOT = Path(__file__).resolve().parents[2]


def test_ways_meet_where_they_cross_or_run_within_reach_and_not_where_they_keep_apart() -> None:
    east = np.array([[0.0, 0.0], [20.0, 0.0]])
    north = np.array([[10.0, -10.0], [10.0, 10.0]])
    beside = np.array([[0.0, 4.0], [20.0, 4.0]])
    assert ways_meet(east, north, 2.0)
    assert not ways_meet(east, beside, 2.0)  # 4 m apart
    assert ways_meet(east, beside, 4.5)
    short_of_it = np.array([[10.0, -10.0], [10.0, -3.0]])  # ends 3 m before the way
    assert not ways_meet(east, short_of_it, 2.5) and ways_meet(east, short_of_it, 3.5)
    assert not ways_meet(east, np.empty((0, 2)), 10.0)


def test_the_distance_to_meeting_is_measured_along_the_way_to_its_first_point_within_reach() -> None:
    east = np.array([[0.0, 0.0], [20.0, 0.0]])
    north = np.array([[10.0, -10.0], [10.0, 10.0]])
    assert distance_to_meeting(east, north, 2.0) == pytest.approx(8.0, abs=0.5)
    bend = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 10.0]])  # 4 m east, then north along x = 4
    assert distance_to_meeting(bend, np.array([[0.0, 6.0], [10.0, 6.0]]), 1.0) == pytest.approx(9.0, abs=0.5)
    assert distance_to_meeting(east, np.array([[0.0, 4.0], [20.0, 4.0]]), 2.0) is None  # 4 m apart
    assert distance_to_meeting(east, np.empty((0, 2)), 10.0) is None


@pytest.mark.parametrize(("distance", "speed", "expected"), [
    (0.3, 0.0, True),  # standing at its line
    (40.0, 14.0, True),  # 14 m/s stops in 32.7 m at 3 m/s²
    (30.0, 14.0, False),  # ... not in 30
    (0.3, 1.5, False),  # 0.3 m from its line at 1.5 m/s: 0.375 m to stop
    (-1.0, 0.0, True),  # its front a little past the lane's end, standing
])
def test_a_driver_waits_only_if_it_can_stop_before_its_line(distance: float, speed: float, expected: bool) -> None:
    assert can_stop_before(distance, speed) is expected


def test_the_way_through_follows_the_internal_lanes_to_the_exit() -> None:
    shapes = {":C_1_0": np.array([[0.0, 0.0], [5.0, 0.0]]), ":C_9_0": np.array([[5.0, 0.0], [5.0, 5.0]]),
              "out_0": np.array([[5.0, 5.0], [5.0, 100.0]])}
    nexts = {":C_1_0": ":C_9_0", ":C_9_0": "out_0"}
    way = way_through(":C_1_0", shapes.__getitem__, nexts.get)
    assert way.tolist() == [[0.0, 0.0], [5.0, 0.0], [5.0, 0.0], [5.0, 5.0]]  # not into the exit


def test_incoming_lanes_are_the_links_normal_from_lanes() -> None:
    controlled = [[("a_0", "b_0", ":C_0_0")], [("a_1", "c_0", ":C_1_0")], [(":C_7_0", "d_0", "")]]
    assert incoming_lanes(controlled) == frozenset({"a_0", "a_1"})


E_LEFT = ROOT / "scenarios/nominal/e_irregular_oblique-left.yaml"
# base seed 20261206's: SUMO's driver reaches the waiting point of its left turn on its green and,
# without the rule, stands there to the end (docs/tried/world.md)
CAUGHT_SEED = 466267842


@pytest.mark.slow
@pytest.mark.parametrize("let_out", [True, False])
def test_sumos_driver_caught_at_its_waiting_point_gets_out_when_the_cross_street_lets_it(let_out: bool) -> None:
    cfg = replace(to_world_config(load_scenario(E_LEFT), E_LEFT.parent), let_out=let_out)
    # how long each driver has waited in a row while all it waits for stood still (a caught one
    # that moves is let out however long it has been caught)
    waited_s: dict[str, float] = defaultdict(float)
    longest_s = 0.0
    waited_for_ego = False
    with World(cfg) as world:
        # SUMO's driver never clearing past those inside the junction: the letting out alone gets it out
        driver = replace(SumoDriverPolicy().driver, clear_through_after_s=None)
        world.reset(CAUGHT_SEED, sumo_driver=driver)
        outcome = None
        while outcome is None:
            _, outcome = world.step(None)
            waiting = world._letting_out.waiting
            waited_for_ego |= any(EGO_ID in whom for whom in waiting.values())
            for vid in list(waited_s):
                if vid not in waiting or any(world.session.vehicle_pose(w)[3] > letting_out.MOVING_MPS
                                             for w in waiting[vid] if w == EGO_ID or w in world.session.vehicle_ids):
                    del waited_s[vid]
            for vid in waiting:
                waited_s[vid] += 0.1
                longest_s = max(longest_s, waited_s[vid])
    if let_out:
        assert outcome.kind == "passed", outcome
        assert waited_for_ego  # the cross street waited for the ego
        assert 0.0 < longest_s <= LET_OUT_FOR_S + 2 * CHECK_EVERY_S  # and no one longer than the rule's bound
    else:
        assert outcome.kind == "timeout" and longest_s == 0.0

