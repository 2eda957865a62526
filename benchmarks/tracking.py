"""Path tracking with no traffic on every candidate path of the six intersections (paper Sec. V-B).

    .venv/bin/python benchmarks/tracking.py --policy models/apg.pt      # a trained IDC policy
    .venv/bin/python benchmarks/tracking.py --policy rule               # the rule-based baseline
    .venv/bin/python benchmarks/tracking.py --policy models/apg.pt --model-optimum --intersections c_three_lane

For each intersection, task and candidate path, the ego starts on the path's entrance lane, the
light is green, nobody else is on the road, and the controller drives that one path (it is the
only candidate it is given) until it leaves the intersection. Every step records the distance
error √(Δx² + Δy²) to the path and the speed error against the pass-mode profile. The table prints
their maxima (and the 99th percentile) per path; the paper claims tracking error ≤ 0.2 m and speed
error < 3 m/s everywhere.

``--model-optimum`` drives with the receding-horizon optimum of the checkpoint's own training model
instead of its policy (``probing.ModelOptimumController``, 0.5–1.4 s a step: pick intersections): what a
policy that had reached its cost's optimum would track.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from crossroads.constants import L_F, L_R, STEER_MAX

from crossroads.evaluation.policies import load_controller
from crossroads.policy.ref import parse_policy
from crossroads.idc.controller import Controller
from crossroads.intersections import catalogue
from crossroads.network.road import TASKS
from crossroads.sim.config import EgoStart, WorldConfig
from crossroads.sim.traffic import NO_TRAFFIC
from crossroads.sim.world import World

TRACKING_TARGET_M = 0.2
# The tightest curve the ego can follow at all (kinematic bicycle at full lock); a path bending
# harder somewhere cannot be tracked exactly by any controller (the paper's Bezier puts such a hook
# at one end of some right turns): such rows are marked "*".
MAX_CURVATURE = math.tan(STEER_MAX) / (L_F + L_R)  # [1/m]
SPEED_TARGET_MPS = 3.0


def drive_one_path(world: World, path_index: int, controller: Controller, seed: int
                   ) -> tuple[np.ndarray, np.ndarray, str]:
    """Distance and speed errors of every step of one episode on one candidate path."""
    path = world.candidates[path_index]
    obs = world.reset(seed)
    controller.reset([path])
    distance, speed = [], []
    outcome = None
    while outcome is None:
        decision = controller.decide(obs)
        obs, outcome = world.step(decision.action)
        x, y, vx = obs.ego[0], obs.ego[1], obs.ego[2]
        here = path.project(x, y)
        if here.s_m >= path.length_m - 1e-6:
            break  # past the end of the path: nothing left to track
        distance.append(abs(here.lateral_m))
        speed.append(abs(vx - path.reference_at(here.s_m, "pass")[3]))
    return np.asarray(distance), np.asarray(speed), outcome.kind if outcome else "end of path"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", default="rule", help="'rule' or a checkpoint (.pt)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--intersections", nargs="*", default=None)
    parser.add_argument("--paths", nargs="*", default=None,
                        help="only these path ids (e.g. left-2), on every intersection driven")
    parser.add_argument("--model-optimum", action="store_true",
                        help="drive the checkpoint's model optimum instead of its policy (slow)")
    args = parser.parse_args()
    if args.model_optimum:
        if args.policy == "rule" or "+" in args.policy:
            parser.error("--model-optimum: --policy must be a trained checkpoint (.pt)")
        sys.path.insert(0, str(Path(__file__).resolve().parent / "research"))  # the research probes
        from probing import ModelOptimumController

        from crossroads.rl.checkpoint import load_networks

        networks, _ = load_networks(Path(args.policy))
        make = lambda: ModelOptimumController(networks.policy, networks.value)  # noqa: E731
    else:
        make = lambda: load_controller(parse_policy(args.policy))  # noqa: E731

    names = args.intersections or catalogue.list_intersections()
    print(f"policy {args.policy}{' (its model optimum)' if args.model_optimum else ''}; no traffic, green light, pass mode; "
          f"targets: tracking <= {TRACKING_TARGET_M} m, speed error < {SPEED_TARGET_MPS} m/s")
    print(f"{'intersection':<22}{'path':<12}{'steps':>6}{'track max':>11}{'track p99':>11}"
          f"{'speed max':>11}{'speed p99':>11}{'max κ':>9}  outcome")
    worst_track, worst_speed, n_paths = 0.0, 0.0, 0
    feasible_track, n_feasible = 0.0, 0
    for name in names:
        net = catalogue.build(name)
        for task in TASKS:
            base = WorldConfig(net_file=net, task=task, demand=NO_TRAFFIC, warmup_s=1.0, timeout_s=60.0)
            with World(base) as probe:
                paths = probe.candidates
            for k, path in enumerate(paths):
                if args.paths is not None and path.id not in args.paths:
                    continue
                config = replace(base, ego_start=EgoStart(entrance_lane=path.entrance_lane))
                with World(config) as world:
                    distance, speed, outcome = drive_one_path(world, k, make(), args.seed)
                if len(distance) == 0:
                    continue
                n_paths += 1
                worst_track = max(worst_track, float(distance.max()))
                worst_speed = max(worst_speed, float(speed.max()))
                if np.abs(path.curvature).max() <= MAX_CURVATURE:
                    n_feasible += 1
                    feasible_track = max(feasible_track, float(distance.max()))
                print(f"{name:<22}{path.id:<12}{len(distance):>6}{distance.max():>11.3f}"
                      f"{np.percentile(distance, 99):>11.3f}{speed.max():>11.2f}"
                      f"{np.percentile(speed, 99):>11.2f}{np.abs(path.curvature).max():>9.2f}"
                      f"{'*' if np.abs(path.curvature).max() > MAX_CURVATURE else ' '} {outcome}")
    print(f"* the path bends harder than the ego's tightest curve ({MAX_CURVATURE:.3f} 1/m at full lock)")
    print(f"{n_paths} paths: worst tracking error {worst_track:.3f} m "
          f"({'met' if worst_track <= TRACKING_TARGET_M else 'NOT met'}), worst speed error "
          f"{worst_speed:.2f} m/s ({'met' if worst_speed < SPEED_TARGET_MPS else 'NOT met'})")
    print(f"{n_feasible} paths the ego can follow at full lock: worst tracking error {feasible_track:.3f} m "
          f"({'met' if feasible_track <= TRACKING_TARGET_M else 'NOT met'})")


if __name__ == "__main__":
    main()
