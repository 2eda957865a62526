"""The judge: leaving the junction by an exit that is not the task's ends the episode as off_road
(before the ego drives on so far from its SUMO route that SUMO cannot place it)."""

from __future__ import annotations

import numpy as np

from crossroads.intersections import catalogue
from crossroads.sim.config import WorldConfig
from crossroads.sim.traffic import NO_TRAFFIC
from crossroads.sim.world import World


def test_driving_straight_on_in_a_left_turn_is_a_wrong_exit() -> None:
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", demand=NO_TRAFFIC,
                         warmup_s=0.0, timeout_s=60.0, perception_noise=False)
    with World(config) as world:
        world.reset(1)
        outcome = None
        while outcome is None:  # wheel held straight, cruising: straight over the junction
            _, outcome = world.step(np.array([0.0, 0.0]))
    assert outcome.kind == "off_road"
    assert outcome.detail == "left the junction by an exit other than its task's"
    assert world.stop_line_crossed_s is not None and outcome.time_s < 20.0
