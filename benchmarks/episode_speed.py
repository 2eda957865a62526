"""Control steps per second of the whole loop against bare SUMO stepping, on the same scene.

    .venv/bin/python benchmarks/episode_speed.py [--intersection c_three_lane] [--steps 1500]

Whole loop = SUMO step + the ego's f_ego and its mirroring into SUMO + snapshot + perception
(sensors and noise) + the IDC state of every candidate path + the rule controller + the outcome
judge. Bare = SUMO stepping the same traffic (same net, same routes, same seed) with nothing else.
Both run in this one process, one after the other, on one core (torch/numpy threads pinned to 1).
Times are this process's CPU time (time.process_time): the work of the one core, which other load on
the machine (a training run, a test suite) does not inflate the way it inflates wall time. The
wall-clock rate is printed too.
Targets (issue #3): whole loop ≤ 3× bare SUMO, and ≥ 300 control steps/s.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

from crossroads.idc.rule_based import RuleBasedController  # noqa: E402
from crossroads.idc.state import build_states, select_others  # noqa: E402
from crossroads.intersections import catalogue  # noqa: E402
from crossroads.sim.config import WorldConfig  # noqa: E402
from crossroads.sim.sumo import SumoSession  # noqa: E402
from crossroads.sim.world import World  # noqa: E402

WARMUP_S = 60.0


def whole_loop_block(world: World, seed: int, steps: int) -> tuple[float, float]:
    """(CPU, wall) seconds per control step over ``steps`` steps of one episode from ``world.reset(seed)``."""
    controller = RuleBasedController()
    obs = world.reset(seed)
    controller.reset(world.candidates)
    done, elapsed, wall = 0, 0.0, 0.0
    while done < steps:
        w0 = time.perf_counter()
        t0 = time.process_time()
        others = select_others(obs.ego, obs.perceived.observations, obs.perceived.kinds)
        decision = controller.decide(obs)
        build_states(obs.ego, others, world.candidates, decision.speed_mode)
        obs, outcome = world.step(decision.action)
        elapsed += time.process_time() - t0
        wall += time.perf_counter() - w0
        done += 1
        if outcome is not None:  # keep measuring in a fresh episode (reset not timed)
            obs = world.reset(seed + done)
            controller.reset(world.candidates)
    return elapsed / steps, wall / steps


def bare_block(world: World, seed: int, steps: int) -> tuple[float, int]:
    """Seconds per bare SUMO step from the same start (same net, routes, seed, warm-up)."""
    world.reset(seed)
    session: SumoSession = world.session
    participants = len(session.snapshot())
    t0 = time.process_time()
    for _ in range(steps):
        session.step()
    return (time.process_time() - t0) / steps, participants


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--intersection", default="c_three_lane")
    parser.add_argument("--task", default="left")
    parser.add_argument("--steps", type=int, default=300, help="steps per round")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    import torch

    torch.set_num_threads(1)
    config = WorldConfig(net_file=catalogue.build(args.intersection), task=args.task,
                         warmup_s=WARMUP_S, timeout_s=60.0)
    loop_times, bare_times, counts, wall_times = [], [], [], []
    with World(config) as world:
        for r in range(args.rounds):  # interleaved, so drift of the machine hits both alike
            seed = args.seed + r
            bare, n = bare_block(world, seed, args.steps)
            bare_times.append(bare)
            counts.append(n)
            cpu, wall = whole_loop_block(world, seed, args.steps)
            loop_times.append(cpu)
            wall_times.append(wall)
        n_candidates = len(world.candidates)
    loop, bare = float(np.median(loop_times)), float(np.median(bare_times))
    print(f"scene: {args.intersection}, task {args.task}, {n_candidates} candidate paths, "
          f"~{np.mean(counts):.0f} participants at the ego's entry; {args.rounds} interleaved rounds "
          f"of {args.steps} steps (medians)")
    print(f"bare SUMO stepping : {1 / bare:8.0f} steps/s  ({1e3 * bare:.2f} ms/step)")
    print(f"whole control loop : {1 / loop:8.0f} steps/s  ({1e3 * loop:.2f} ms/step)")
    print(f"loop cost / bare   : {loop / bare:8.2f} x   (target <= 3.0: {'met' if loop / bare <= 3 else 'NOT met'})")
    print(f"control steps/s    : {1 / loop:8.0f}     (target >= 300: {'met' if 1 / loop >= 300 else 'NOT met'})")
    wall = float(np.median(wall_times))
    print(f"wall clock         : {1 / wall:8.0f} control steps/s (CPU time above; this one includes waits for "
          f"the core when the machine is busy)")

if __name__ == "__main__":
    main()
