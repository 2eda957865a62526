"""The online IDC decision with (untrained) networks of the paper's shape, in the real world."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import NamedTuple

import numpy as np
import pytest
import torch

from crossroads.constants import EGO_LENGTH_M, JERK_MAX, STEER_RATE_MAX, STOP_LINE_GAP_M
from crossroads.idc.crosswalks import CrossingSpan, crossing_spans
from crossroads.idc.decision import (
    HELD_CROSSING_RELEASE_STEPS,
    NEAR_TIE_ABSOLUTE,
    NEAR_TIE_RELATIVE,
    IdcController,
    braking_distance,
    first_identical,
    least_value_path,
)
from crossroads.idc.rule_based import RuleBasedController
from crossroads.idc.shield import HOLD_WHEEL
from crossroads.idc.state import build_states, select_others
from crossroads.intersections import catalogue
from crossroads.planning import CandidatePath
from crossroads.rl.checkpoint import load_networks
from crossroads.rl.neural_nets import make_networks
from crossroads.sim.config import SignalStart, WorldConfig
from crossroads.sim.ego import braking_distance_m
from crossroads.sim.traffic import NO_TRAFFIC
from crossroads.sim.observation import Observation, Perceived
from crossroads.sim.world import World
from support import REPO_ROOT



def shipped_with_shield(model: str) -> IdcController:
    """A shipped model's networks in the IDC decision with the shield (``--policy models/MODEL+shield``)."""
    networks, _ = load_networks(REPO_ROOT / "models" / model)
    return IdcController(networks.policy, networks.value, name=model.removesuffix(".pt") + "+shield", shield=True)

def test_value_picks_the_path_and_policy_gives_the_action() -> None:
    torch.manual_seed(0)
    nets = make_networks("dpg", hidden_layers=5, hidden_units=256)
    controller = IdcController(nets.policy, nets.value)
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", warmup_s=20.0)
    with World(config) as world:
        obs = world.reset(4)
        controller.reset(world.candidates)
        for _ in range(20):
            decision = controller.decide(obs)
            mode = controller.speed_mode(obs)
            others = select_others(obs.ego, obs.perceived.observations, obs.perceived.kinds)
            states = torch.from_numpy(build_states(obs.ego, others, world.candidates, mode)).float()
            with torch.no_grad():
                values = nets.value(states).numpy()
                expected = nets.policy.mean_action(states[decision.path_index][None])[0].numpy()
            assert decision.path_index == least_value_path(values)  # argmin, near-ties to the first path
            np.testing.assert_allclose(decision.path_values, values, rtol=1e-6)
            np.testing.assert_allclose(decision.action, expected, rtol=1e-6)
            assert abs(decision.action[0]) <= STEER_RATE_MAX and abs(decision.action[1]) <= JERK_MAX
            obs, outcome = world.step(decision.action)
            if outcome is not None:
                break


def test_the_shield_keeps_the_policys_action_or_brakes_with_the_wheel_held() -> None:
    torch.manual_seed(0)
    nets = make_networks("dpg", hidden_layers=5, hidden_units=256)
    plain = IdcController(nets.policy, nets.value)
    shielded = IdcController(nets.policy, nets.value, shield=True)
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", warmup_s=20.0)
    braked = 0
    with World(config) as world:
        obs = world.reset(4)
        plain.reset(world.candidates)
        shielded.reset(world.candidates)
        for _ in range(80):
            own, checked = plain.decide(obs), shielded.decide(obs)
            assert own.shield_braking is None and checked.shield_braking is not None
            assert checked.path_index == own.path_index and checked.speed_mode == own.speed_mode
            if checked.shield_braking:
                braked += 1
                assert np.array_equal(checked.action, HOLD_WHEEL)
            else:
                np.testing.assert_allclose(checked.action, own.action, atol=1e-6)
            obs, outcome = world.step(checked.action)
            if outcome is not None:
                break
    assert braked > 0  # an untrained policy drives into the traffic: the shield has work


@pytest.mark.parametrize("model", ["apg.pt", "dpg.pt"])
def test_with_the_shield_a_shipped_model_stands_short_of_a_red_line(model: str) -> None:
    """On an empty road, starting 40 m from a red line at 8.33 m/s: bare, the shipped APG crossed
    the line on red at 4.7 m/s (docs/tried/world.md, "Red lights"); with the shield, which treats the
    line as a standing obstacle while the light holds the ego, the bumper stands 0.50 m short until
    green (measured: 0.500–0.505 m for APG, 0.501–0.502 m for DPG)."""
    controller = shipped_with_shield(model)
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", demand=NO_TRAFFIC,
                         signal_start=SignalStart(ego_light="red"), warmup_s=1.0, timeout_s=60.0)
    gaps_standing_on_red = []
    with World(config) as world:
        obs = world.reset(0)
        controller.reset(world.candidates)
        while obs.light.light == "red":
            if obs.ego[2] < 0.05:
                gaps_standing_on_red.append(obs.distance_to_stop_line_m)
            obs, outcome = world.step(controller.decide(obs).action)
            assert outcome is None or outcome.kind != "red_light", outcome
    assert len(gaps_standing_on_red) > 100  # it waited for the green (the ego's red lasts 40 s here)
    assert STOP_LINE_GAP_M - 0.05 < min(gaps_standing_on_red) and max(gaps_standing_on_red) < STOP_LINE_GAP_M + 0.3


class ExitCrossingScene(NamedTuple):
    """The nominal left turn's start on an empty c_three_lane, a shielded APG reset to it, and a
    pedestrian standing on the exit crossing in the ego's path."""

    controller: IdcController
    obs: Observation  # the start, nobody perceived
    path: CandidatePath  # candidate 0
    entry: CrossingSpan
    exit: CrossingSpan
    seen: Perceived  # the pedestrian on the exit crossing


@pytest.fixture
def exit_crossing() -> Iterator[ExitCrossingScene]:
    controller = shipped_with_shield("apg.pt")
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", demand=NO_TRAFFIC, warmup_s=1.0)
    with World(config) as world:
        obs = world.reset(0)
        controller.reset(world.candidates)
        path = world.candidates[0]
        entry, exit_ = crossing_spans(path.points, path.s, obs.crossings)
        on_exit = exit_.centre.interpolate(0.5, normalized=True)
        pedestrian = np.array([[on_exit.x, on_exit.y, 0.0, 0.0, 0.3, 0.5]])
        yield ExitCrossingScene(controller, obs, path, entry, exit_,
                                Perceived(np.array([0]), np.array(["pedestrian"]), pedestrian))


def test_the_shields_line_is_a_crossing_a_pedestrian_claims_ahead(exit_crossing: ExitCrossingScene) -> None:
    """The shield holds the ego short of a crossing a pedestrian claims (idc.crosswalks): the line it
    gets is the front bumper's distance to the exit crossing while someone stands on it in the ego's
    path, and none when nobody does or when the light's line is nearer."""
    controller, obs, path, entry, exit_, seen = exit_crossing
    front_s = path.project(float(obs.ego[0]), float(obs.ego[1])).s_m + EGO_LENGTH_M / 2.0
    claimed_obs = dataclasses.replace(obs, perceived=seen)
    line, span = controller._shield_line(False, claimed_obs, 0)
    assert line == pytest.approx(exit_.s_in_m - front_s) and span == exit_
    assert controller._shield_line(False, obs, 0) == (None, None)  # nobody on it
    # a held stop line nearer than the crossing wins
    line, span = controller._shield_line(True, claimed_obs, 0)
    assert line == pytest.approx(obs.distance_to_stop_line_m) and span is None
    assert entry.s_in_m < exit_.s_in_m


def test_a_crossing_the_shield_braked_for_stays_its_line_while_claimed_and_green(exit_crossing: ExitCrossingScene) -> None:
    """Once the shield has braked for a claimed crossing, the crossing stays its line even where full
    braking can no longer stand short of it (the ego then stops just onto it, not metres in), until
    nobody has claimed it for HELD_CROSSING_RELEASE_STEPS steps or the light is no longer green."""
    controller, obs, path, _, exit_, seen = exit_crossing
    nobody = Perceived(np.zeros(0, int), np.zeros(0, str), np.zeros((0, 6)))
    # the ego at 6 m/s with its front bumper 1 m short of the exit crossing: too late to stand short
    i = int(np.searchsorted(path.s, exit_.s_in_m - 1.0 - EGO_LENGTH_M / 2.0))
    ego = np.array([path.points[i, 0], path.points[i, 1], 6.0, 0.0, path.heading[i], 0.0, 0.0, 0.0])
    late = dataclasses.replace(obs, ego=ego, perceived=seen)
    assert controller._shield_line(False, late, 0) == (None, None)
    controller._held_crossing = (0, exit_)  # what decide() keeps when the shield brakes for the crossing
    line, span = controller._shield_line(False, late, 0)
    assert span is exit_ and line == pytest.approx(exit_.s_in_m - path.s[i] - EGO_LENGTH_M / 2.0)
    unclaimed = dataclasses.replace(late, perceived=nobody)
    for _ in range(HELD_CROSSING_RELEASE_STEPS - 1):  # a claim flickering off keeps the line
        assert controller._shield_line(False, unclaimed, 0)[1] is exit_
    assert controller._shield_line(False, unclaimed, 0) == (None, None)  # released
    controller._held_crossing = (0, exit_)
    not_green = dataclasses.replace(late, light=dataclasses.replace(late.light, light="yellow"))
    assert controller._shield_line(False, not_green, 0) == (None, None)  # clear the junction instead
    assert controller._held_crossing is None


@pytest.mark.parametrize(("values", "best"), [
    ([3.0, 1.0, 2.0], 1),                   # a clear least
    ([14.909682, 14.909680], 0),            # torch's near-tie of the fine-tuned APG: the first path
    ([14.909687, 14.909688], 0),            # onnxruntime's, the other way round: the first again
    ([2.0, 1.0, 1.000001], 1),              # a tie after the least goes to the least (the first of them)
    ([1.0001, 1.0], 1),                     # 1e-4 apart is a real difference
    ([1e-7, 0.0, 5.0], 0),                  # near zero the absolute floor decides
    ([-10.0, -10.00001], 0),                # negative values: relative to |least|
])
def test_the_path_of_least_value_with_near_ties_to_the_first(values: list[float], best: int) -> None:
    assert least_value_path(np.array(values)) == best


@pytest.mark.parametrize(("preview", "encoder"), [(False, 0), (True, 0), (True, 16)])
def test_one_normalisation_for_both_networks_gives_the_same_decision(preview: bool, encoder: int) -> None:
    torch.manual_seed(3)
    nets = make_networks("dpg", 2, 32, preview=preview, encoder=encoder)
    controller = IdcController(nets.policy, nets.value)
    assert controller._shared_input
    states = np.random.default_rng(5).normal(size=(40, 3, 120 if preview else 108)) * 5.0
    for candidates in states:
        shared = controller.decide_states(candidates)
        controller._shared_input = False
        apart = controller.decide_states(candidates)
        controller._shared_input = True
        assert shared[0] == apart[0]
        np.testing.assert_array_equal(shared[1], apart[1])
        np.testing.assert_array_equal(shared[2], apart[2])


def original_decision(controller: IdcController, states: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """(τ*, action, values) of the candidates' ``states`` computed plainly: the networks' own forward
    (their torch normalisation of every row, a module call per layer), the values picked by
    first_identical and the near tie in numpy: what the decision's fast path must give bit for bit."""
    x = torch.from_numpy(states).to(controller._dtype)
    with torch.inference_mode():
        values = controller.value(x)[torch.from_numpy(first_identical(states))].double().numpy()
        least = float(values.min())
        best = int(np.argmax(values <= least + NEAR_TIE_RELATIVE * abs(least) + NEAR_TIE_ABSOLUTE))
        action = controller.policy.mean_action(x[best:best + 1])[0].double().numpy()
    return best, action, values


@pytest.mark.parametrize("model", ["apg.pt", "dpg.pt", "pooled/apg.pt"])
def test_the_decision_is_the_plain_computation_bit_for_bit_on_a_real_episode(model: str) -> None:
    """The decision's fast path (the shared rows normalised once, the networks' fetched functions,
    the pick on Python floats) on observations of a real episode, the rule controller driving the
    nominal left turn through traffic: the same path, values and action as the plain computation
    (``original_decision``), bit for bit, for the shipped models (APG with the path preview, DPG
    without, the pooled APG with the lead summary too)."""
    networks, _ = load_networks(REPO_ROOT / "models" / model)
    controller = IdcController(networks.policy, networks.value)
    driver = RuleBasedController()
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", warmup_s=60.0)
    chosen = set()
    with World(config) as world:
        obs = world.reset(0)
        controller.reset(world.candidates)
        driver.reset(world.candidates)
        for _ in range(250):
            decision = controller.decide(obs)
            others = select_others(obs.ego, obs.perceived.observations, obs.perceived.kinds)
            states = build_states(obs.ego, others, world.candidates, controller.speed_mode(obs), controller.preview)
            best, action, values = original_decision(controller, states)
            assert decision.path_index == best
            assert decision.path_values.tobytes() == values.tobytes()
            assert decision.action.dtype == np.float64 and decision.action.tobytes() == action.tobytes()
            chosen.add(best)
            obs, outcome = world.step(driver.decide(obs).action)
            if outcome is not None:
                break
    assert chosen == {0, 1, 2}  # the values chose every path somewhere: the pick was exercised


def test_the_decision_is_the_plain_computation_on_random_candidates() -> None:
    """The same on random candidates' states sharing x_ego and x_other, some rows repeated (a tie
    to the first) and some not sharing (the normalisation of every row)."""
    torch.manual_seed(4)
    nets = make_networks("apg", 3, 64, preview=True)
    controller = IdcController(nets.policy, nets.value)
    rng = np.random.default_rng(9)
    for k in range(200):
        states = np.repeat(rng.normal(size=(1, 120)) * 10.0, 3, axis=0)
        states[:, 8:12] = rng.normal(size=(3, 4))
        states[:, 108:] = rng.normal(size=(3, 12))
        if k % 4 == 1:
            states[2] = states[0]  # identical candidates: one value, the first's
        if k % 4 == 2:
            states[1, 20] += 1.0  # rows that do not share x_other
        best, action, values = controller.decide_states(states)
        expected = original_decision(controller, states)
        assert best == expected[0]
        assert action.tobytes() == expected[1].tobytes() and values.tobytes() == expected[2].tobytes()


def test_least_value_path_on_python_floats_is_numpys() -> None:
    """The pick on Python floats is the numpy formula's, NaN and infinities included."""
    rng = np.random.default_rng(2)
    specials = [np.nan, np.inf, -np.inf, 0.0, -0.0, 1e-7]
    for _ in range(2000):
        values = rng.normal(10.0, 1e-4, size=int(rng.integers(1, 5)))
        if rng.random() < 0.3:
            values[int(rng.integers(len(values)))] = specials[int(rng.integers(len(specials)))]
        least = float(np.min(values))
        expected = int(np.argmax(values <= least + NEAR_TIE_RELATIVE * abs(least) + NEAR_TIE_ABSOLUTE))
        assert least_value_path(values) == expected, values


def test_the_braking_distance_on_floats_is_the_worlds() -> None:
    """The shield's crossing check steps full braking on Python floats: the distance of
    sim.ego.braking_distance_m, bit for bit, from a stand, at every speed and acceleration."""
    rng = np.random.default_rng(3)
    cases = [(0.0, 0.0), (0.0, 1.5), (1e-9, -3.0), (8.33, 1.5), (8.33, -3.0), (20.0, 9.0), (3.0, -9.0)]
    cases += list(zip(rng.uniform(0.0, 15.0, 300).tolist(), rng.uniform(-4.0, 2.0, 300).tolist()))
    for speed, accel in cases:
        assert braking_distance(speed, accel) == float(braking_distance_m(speed, accel))
