"""Control steps per second of the whole loop against bare SUMO stepping, on the same scene.

    .venv/bin/python benchmarks/episode_speed.py [--intersection c_three_lane] [--steps 1500]

Whole loop = SUMO step + the ego's f_ego and its mirroring into SUMO + snapshot + perception
(sensors and noise) + the IDC state of every candidate path + the rule controller + the outcome
judge. Bare = SUMO stepping the same traffic (same net, same routes, same seed) with nothing else.
Both run in this one process, one after the other, on one core (torch/numpy threads pinned to 1).
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
from crossroads.network import catalogue  # noqa: E402
from crossroads.sim.config import WorldConfig  # noqa: E402
from crossroads.sim.sumo import SumoSession  # noqa: E402
from crossroads.sim.world import World  # noqa: E402

WARMUP_S = 60.0


def whole_loop(world: World, seed: int, steps: int) -> tuple[float, int, float]:
    """Steps/s of the full control loop; restarts the episode whenever one ends."""
    controller = RuleBasedController()
    obs = world.reset(seed)
    controller.reset(world.candidates)
    participants = []
    done = 0
    elapsed = 0.0
    while done < steps:
        t0 = time.perf_counter()
        others = select_others(obs.ego, obs.perceived.observations, obs.perceived.kinds)
        decision = controller.decide(obs)
        build_states(obs.ego, others, world.candidates, decision.speed_mode)
        obs, outcome = world.step(decision.action)
        elapsed += time.perf_counter() - t0
        participants.append(len(obs.participants))
        done += 1
        if outcome is not None:
            seed += 1
            obs = world.reset(seed)
            controller.reset(world.candidates)
    return done / elapsed, done, float(np.mean(participants))


def bare_sumo(world: World, seed: int, steps: int) -> float:
    """Steps/s of SUMO alone on the same net and routes (the world's warm-up path, no ego)."""
    world.reset(seed)  # writes the same routes and starts SUMO the same way
    session: SumoSession = world.session
    t0 = time.perf_counter()
    session.step(steps)
    return steps / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--intersection", default="c_three_lane")
    parser.add_argument("--task", default="left")
    parser.add_argument("--steps", type=int, default=1500)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    import torch

    torch.set_num_threads(1)
    config = WorldConfig(net_file=catalogue.build(args.intersection), task=args.task,
                         warmup_s=WARMUP_S, timeout_s=60.0)
    with World(config) as world:
        bare = bare_sumo(world, args.seed, args.steps)
        loop, n, mean_participants = whole_loop(world, args.seed, args.steps)
        bare_again = bare_sumo(world, args.seed, args.steps)  # bracket the loop: load drift shows
    bare_mean = 0.5 * (bare + bare_again)
    print(f"scene: {args.intersection}, task {args.task}, seed {args.seed}, "
          f"{len(world.candidates)} candidate paths, ~{mean_participants:.0f} participants")
    print(f"bare SUMO stepping : {bare_mean:8.0f} steps/s  (before {bare:.0f}, after {bare_again:.0f})")
    print(f"whole control loop : {loop:8.0f} steps/s  over {n} steps")
    print(f"loop cost / bare   : {bare_mean / loop:8.2f} x   (target <= 3.0)")
    print(f"target >= 300 control steps/s: {'met' if loop >= 300 else 'NOT met'}")


if __name__ == "__main__":
    main()
