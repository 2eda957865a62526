"""Does SUMO's traffic drive into an ego that stands inside the junction?

    .venv/bin/python benchmarks/research/junction_standing_probe.py [--intersection c_three_lane] \
        [--task left] [--seeds 6] [--past-line 6 12] [--stand-s 20]

The rule-based controller drives the scene (nominal traffic, 30 s warm-up); once its front bumper
is ``--past-line`` metres past the stop line it brakes at full jerk to a stand and is held there for
``--stand-s`` seconds. Printed per seed and distance: when it stood, and whether anyone hit it.
Why: the shield's collisions after a long wait were all inside the junction, and whether SUMO's
vehicles see the ego there (it is placed with moveToXY every step, speed mode 0) had not been
checked (docs/tried/shield.md).
"""

from __future__ import annotations

import argparse

import numpy as np

from crossroads.constants import JERK_MAX, SIM_STEP_S
from crossroads.idc.rule_based import RuleBasedController
from crossroads.intersections import catalogue
from crossroads.sim.config import WorldConfig
from crossroads.sim.world import World

STANDING_MPS = 0.05  # [m/s] below this the ego counts as standing


def stand_inside(config: WorldConfig, seed: int, past_line_m: float, stand_s: float) -> tuple[float | None, bool, str]:
    """(the time the ego came to a stand or None, whether it was hit, what ended the run) for one seed."""
    controller = RuleBasedController()
    with World(config) as world:
        obs = world.reset(seed)
        controller.reset(world.candidates)
        t, stood = 0.0, None
        while True:
            action = np.array(controller.decide(obs).action, dtype=float)
            if -obs.distance_to_stop_line_m > past_line_m:
                action[1] = -JERK_MAX  # brake to a stand and stay
                if stood is None and obs.ego[2] < STANDING_MPS:
                    stood = t
            obs, outcome = world.step(action)
            t += SIM_STEP_S
            if outcome is not None:
                return stood, outcome.kind == "collision", f"{outcome.kind}: {outcome.detail}"
            if stood is not None and t - stood >= stand_s:
                return stood, False, f"stood {stand_s:g} s, not hit"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--intersection", default="c_three_lane")
    parser.add_argument("--task", default="left")
    parser.add_argument("--seeds", type=int, default=6, help="seeds 0 … N−1")
    parser.add_argument("--past-line", type=float, nargs="+", default=[6.0, 12.0], help="[m] past the stop line")
    parser.add_argument("--stand-s", type=float, default=20.0)
    args = parser.parse_args()
    config = WorldConfig(net_file=catalogue.build(args.intersection), task=args.task, warmup_s=30.0, timeout_s=60.0)
    hit = stands = 0
    print(f"{'past line [m]':>13} {'seed':>4} {'stood at [s]':>12}  outcome")
    for past in args.past_line:
        for seed in range(args.seeds):
            stood, collided, what = stand_inside(config, seed, past, args.stand_s)
            stands += stood is not None
            hit += stood is not None and collided
            print(f"{past:13.1f} {seed:4d} {'-' if stood is None else f'{stood:.1f}':>12}  {what}", flush=True)
    print(f"stood inside the junction {stands} times, hit after standing: {hit}")


if __name__ == "__main__":
    main()
