"""x_other and each slot's route curvature from an observation (idc.observed), in the real world."""

from __future__ import annotations

import numpy as np

from crossroads.idc.observed import observed_others
from crossroads.idc.rule_based import RuleBasedController
from crossroads.idc.state import select_others, selected_rows
from crossroads.intersections import catalogue
from crossroads.sim.config import WorldConfig
from crossroads.sim.world import World
from crossroads.sim.observation import participant_curvatures


def test_the_slots_get_the_curvatures_of_the_participants_in_them() -> None:
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", warmup_s=30.0)
    controller = RuleBasedController()
    turning = 0
    with World(config) as world:
        obs = world.reset(2)
        controller.reset(world.candidates)
        for _ in range(60):
            seen = obs.perceived
            others, kappa = observed_others(obs)
            assert np.array_equal(others, select_others(obs.ego, seen.observations, seen.kinds))
            # the curvature of every perceived participant, then the same selection: what the
            # sampler computed before the curvature was limited to the slots
            every = participant_curvatures(obs.lane_shapes, seen.lanes(np.arange(len(seen.kinds))),
                                           seen.observations, seen.kinds)
            slots = selected_rows(obs.ego, seen.observations, seen.kinds)
            expected = np.where(slots >= 0, every[slots], 0.0)
            assert np.array_equal(kappa, expected)
            turning += int(np.count_nonzero(kappa))
            obs, outcome = world.step(controller.decide(obs).action)
            if outcome is not None:
                break
    assert turning > 0  # the junction's internal lanes bend: some slots do turn


def test_selected_rows_name_the_rows_of_each_slot_and_pad_the_rest() -> None:
    ego = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    obs = np.array([[30.0, 0, 5, 0, 4.5, 1.8], [10.0, 0, 5, 0, 4.5, 1.8], [5.0, 1, 1, 0, 0.5, 0.5]])
    rows = selected_rows(ego, obs, np.array(["vehicle", "vehicle", "pedestrian"]))
    assert rows[:3].tolist() == [1, 0, -1] and rows[12] == 2 and np.all(rows[13:] == -1)
    assert np.all(selected_rows(ego, np.zeros((0, 6)), np.array([])) == -1)


def test_the_map_matches_each_perceived_participant_to_its_true_lane() -> None:
    """A controller gets the lane of what it perceives through the map matching, not the world's
    true snapshot (which only the judge, the trace and the viewer get)."""
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", warmup_s=30.0)
    with World(config) as world:
        obs = world.reset(2)
        seen, truth = obs.perceived, world.truth.participants
        assert not hasattr(obs, "participants") and not hasattr(obs, "abnormal_ids")
        indices = np.arange(len(seen.kinds))
        assert len(indices) > 0
        assert seen.lanes(indices).tolist() == truth.lane_id[seen.rows].tolist()
