"""Step rate of the Gymnasium environment (Crossroads-v0) beside the bare control loop.

    .venv/bin/python benchmarks/gym_speed.py [--scenario scenarios/nominal/c_three_lane-left.yaml]
                                             [--seeds 3] [--repeats 3] [--inside 2]

The same episodes, the same actions, four ways, alternating, in one process:

* bare: ``World.step(action)`` and nothing else: what the control loop of ``run_episode`` costs
  apart from the controller;
* rule: ``World.step`` and the rule controller's ``decide`` (which gives those actions): the control
  loop of ``crossroads run --policy rule``;
* state: ``World.step`` and the IDC state of every candidate path (light logic, x_other, x_track):
  what an IDC controller computes before its networks run;
* gym: ``CrossroadsEnv.step(action)`` (box observation): the world step, the tracked path and its
  state (built alone), the reward (utility, 60 constraints and their penalty) and the ``info`` dict.

The actions are the rule controller's, recorded once per seed (paper traffic), and replayed; resets
are not timed (all four do the same warm-up). Times are the process's CPU time
(``time.process_time``: libsumo runs in this process), so that other work on a shared machine
counts less; the rates are printed per round with their median and best. The four loops take
turns going first, and gym / bare is also taken pair by pair: per episode (the two run within a
second or two of each other) and per step (bare's time of a step over the environment's of the same
step of the same episode, each step timed on its own). On a loaded machine the episodes' rates swing
by a third from one run to the next; the median of the per-step pairs swings less. ``--inside``
times ``World.step`` inside ``env.step``, on the same steps (wall clock, medians): what the
environment adds to each step, with the load of that moment on both.
The environment's fast paths give the plain formulation's numbers (tests/gym_env/test_exact.py).
Target (issue 40): gym ≥ 90 % of bare.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from crossroads.scenario.spec import load_scenario, run_seeds
from crossroads.gym import CrossroadsEnv
from crossroads.gym.observation import idc_view
from crossroads.gym.reward import RewardConfig, step_reward
from crossroads.idc.rule_based import RuleBasedController
from crossroads.sim.world import World

REPO = Path(__file__).resolve().parents[1]


def record_actions(world: World, seed: int) -> list[np.ndarray]:
    """The rule controller's actions of one episode."""
    controller = RuleBasedController()
    obs, outcome, actions = world.reset(seed), None, []
    controller.reset(world.candidates)
    while outcome is None:
        actions.append(controller.decide(obs).action)
        obs, outcome = world.step(actions[-1])
    return actions


Timed = list[int]  # [ns] the process's CPU time of each step of one loop over one episode


def time_world(world: World, seed: int, actions: list[np.ndarray], states: bool) -> Timed:
    """Each step's time of replaying ``actions`` through the world, with or without the states."""
    world.reset(seed)
    times, clock = [], time.process_time_ns
    last = clock()
    for action in actions:
        obs, outcome = world.step(action)
        if states:
            idc_view(obs, False, "nearest")
        now = clock()
        times.append(now - last)
        last = now
        if outcome is not None:
            break
    return times


def time_rule(world: World, seed: int, actions: list[np.ndarray]) -> Timed:
    """Each step's time of the rule controller driving (its decisions are the recorded actions)."""
    controller = RuleBasedController()
    obs = world.reset(seed)
    controller.reset(world.candidates)
    times, clock = [], time.process_time_ns
    last = clock()
    for _ in actions:
        obs, outcome = world.step(controller.decide(obs).action)
        now = clock()
        times.append(now - last)
        last = now
        if outcome is not None:
            break
    return times


def time_env(env: CrossroadsEnv, seed: int, actions: list[np.ndarray]) -> Timed:
    """Each step's time of replaying ``actions`` through the environment."""
    env.reset(seed=seed)
    times, clock = [], time.process_time_ns
    last = clock()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        now = clock()
        times.append(now - last)
        last = now
        if terminated or truncated:
            break
    return times


def inside_costs(env: CrossroadsEnv, recorded: dict[int, list[np.ndarray]], rounds: int) -> tuple[int, float, float]:
    """(steps, World.step, env.step − World.step) [µs], medians over every step of ``rounds`` passes
    over the episodes, both parts timed in the same call (wall clock, ``perf_counter_ns``): the load
    of the moment weighs on both alike, and a step the scheduler preempted is an outlier the median
    drops."""
    world, clock = env.world, time.perf_counter_ns
    inner, last = world.step, [0]

    def timed(action: np.ndarray) -> Any:
        start = clock()
        out = inner(action)
        last[0] = clock() - start
        return out

    world.step = timed  # type: ignore[method-assign]
    pairs = []
    try:
        for _ in range(rounds):
            for seed, actions in recorded.items():
                env.reset(seed=seed)
                for action in actions:
                    start = clock()
                    _, _, terminated, truncated, _ = env.step(action)
                    pairs.append((last[0], clock() - start - last[0]))
                    if terminated or truncated:
                        break
    finally:
        del world.step  # the method again
    return (len(pairs), statistics.median(w for w, _ in pairs) / 1000,
            statistics.median(e for _, e in pairs) / 1000)


def component_costs(world: World, seed: int, actions: list[np.ndarray], rounds: int = 5) -> dict[str, float]:
    """[µs per step] best of ``rounds`` passes over one episode's observations: the environment's
    work beyond ``World.step`` (the IDC states and the tracked path; the reward)."""
    world.reset(seed)
    observations = []
    for action in actions:
        obs, outcome = world.step(action)
        observations.append(obs)
        if outcome is not None:
            break
    views = [idc_view(obs, False, "nearest") for obs in observations]
    config = RewardConfig()
    costs = {}
    for name, work in (("states", lambda k: idc_view(observations[k], False, "nearest")),
                       ("reward", lambda k: step_reward(config, views[k - 1].state, actions[k], views[k].state, None))):
        best = float("inf")
        for _ in range(rounds):
            start = time.process_time()
            for k in range(1, len(observations)):
                work(k)
            best = min(best, (time.process_time() - start) / (len(observations) - 1))
        costs[name] = 1e6 * best
    return costs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", type=Path, default=REPO / "scenarios/nominal/c_three_lane-left.yaml")
    parser.add_argument("--seeds", type=int, default=3, help="episodes (the scenario's first run seeds)")
    parser.add_argument("--repeats", type=int, default=3, help="rounds of the four loops, alternating")
    parser.add_argument("--inside", type=int, default=0, metavar="ROUNDS",
                        help="also time World.step inside env.step, step by step, over ROUNDS passes")
    args = parser.parse_args()

    spec = load_scenario(args.scenario)
    seeds = run_seeds(spec, args.seeds)
    env = CrossroadsEnv(args.scenario)
    world = env.world  # one World (libsumo: one simulation per process), driven directly or by the env
    recorded = {seed: record_actions(world, seed) for seed in seeds}
    runs = {"bare": lambda seed, actions: time_world(world, seed, actions, False),
            "rule": lambda seed, actions: time_rule(world, seed, actions),
            "state": lambda seed, actions: time_world(world, seed, actions, True),
            "gym": lambda seed, actions: time_env(env, seed, actions)}
    rates: dict[str, list[float]] = {name: [] for name in runs}
    paired: list[float] = []  # gym / bare of one episode, the two run one after the other
    per_step: list[float] = []  # bare / gym time of one step, the same step of the same episode
    names = list(runs)
    try:
        for round_index in range(args.repeats):
            totals: dict[str, list[float]] = {k: [0, 0.0] for k in rates}
            for k, (seed, actions) in enumerate(recorded.items()):
                # the loops in turn, each first in some episode: load that drifts favours none
                shift = (round_index + k) % len(names)
                episode = {}
                for name in names[shift:] + names[:shift]:
                    episode[name] = runs[name](seed, actions)
                    totals[name][0] += len(episode[name])
                    totals[name][1] += 1e-9 * sum(episode[name])
                paired.append((len(episode["gym"]) / sum(episode["gym"])) / (len(episode["bare"]) / sum(episode["bare"])))
                per_step.extend(b / g for b, g in zip(episode["bare"], episode["gym"]))
            for name, (steps, seconds) in totals.items():
                rates[name].append(steps / seconds)
        first = next(iter(recorded))
        costs = component_costs(world, first, recorded[first])
        inside = inside_costs(env, recorded, args.inside) if args.inside else None
    finally:
        env.close()
    steps = sum(len(a) for a in recorded.values())
    print(f"{spec.name}: {len(seeds)} episodes, {steps} recorded steps, {args.repeats} rounds "
          f"(steps/s per round; median)")
    for name, values in rates.items():
        print(f"  {name:5s} {' '.join(f'{v:7.0f}' for v in values)}   median {statistics.median(values):7.0f}"
              f"   best {max(values):7.0f}")
    world_us = 1e6 / max(rates["bare"])
    print(f"per step, best of 5 over one episode: the states {costs['states']:.0f} µs, the reward "
          f"{costs['reward']:.0f} µs; World.step {world_us:.0f} µs (best round): their share "
          f"{100 * world_us / (world_us + costs['states'] + costs['reward']):.1f} %")
    print(f"paired: gym / bare per episode, the median of {len(paired)}: {100 * statistics.median(paired):.1f} % "
          f"(quartiles {' – '.join(f'{100 * q:.1f}' for q in statistics.quantiles(paired, n=4)[::2])} %)")
    print(f"paired per step: bare / gym time of the same step, the median of {len(per_step)}: "
          f"{100 * statistics.median(per_step):.1f} % (quartiles "
          f"{' – '.join(f'{100 * q:.1f}' for q in statistics.quantiles(per_step, n=4)[::2])} %)")
    if inside is not None:
        n, world_us, extra_us = inside
        print(f"inside env.step, the median of {n} steps: World.step {world_us:.0f} µs, the rest {extra_us:.1f} µs: "
              f"gym / bare = {100 * world_us / (world_us + extra_us):.1f} %")
    for label, pick in (("median", statistics.median), ("best", max)):
        gym = pick(rates["gym"])
        print(f"{label}: gym / " + ", gym / ".join(f"{name} = {100 * gym / pick(rates[name]):.1f} %"
                                                   for name in ("bare", "rule", "state")) + " (target >= 90 %)")


if __name__ == "__main__":
    main()
