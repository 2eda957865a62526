"""What does the training model charge for driving at a standing car? The cost of three plans.

    .venv/bin/python benchmarks/research/queue_cost.py --policy models/apg.pt [--tail 0 40]

The same scene as benchmarks/research/queue_response.py (``standing_car_scene``: a car standing on c_three_lane's straight path a
bumper gap d ahead of the ego at speed v, pass mode, every other slot padded), but instead of
driving it in closed loop this prints what the differentiable model (rl.idc_model, with the braking
floor the shipped runs train with) charges over one horizon of T = 25 steps for three plans: the
policy's mean actions, full braking (Δa = −4.5 m/s³ every step) and coasting (Δa = 0), as
J = J_track + ρ J_safe with ρ = 15, once per ``--tail`` (the stopping tail's steps; 0 = the paper's
model). Where braking costs less than the policy's plan the model asks the policy to brake; where
it costs more, no amount of training on that state will teach the stop.

``--trace V D`` instead drives the one cell (V m/s, D m) in closed loop in the same model (as
queue_response.py does, the policy's mean action every 0.1 s) and prints, every 0.4 s, the gap, the
ego's speed and acceleration, the policy's Δa and what the model (with the first ``--tail``)
predicts for the policy's plan from there: does the policy act on the danger its model sees?
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

from crossroads.constants import HORIZON_T, JERK_MAX, PENALTY_RHO  # noqa: E402
from crossroads.constants import EGO_LENGTH_M  # noqa: E402
from crossroads.idc.state import N_OTHERS, path_tensors  # noqa: E402
from crossroads.rl.augment import CAR_LENGTH_M  # noqa: E402
from crossroads.intersections import catalogue  # noqa: E402
from crossroads.rl.buffer import StateBatch  # noqa: E402
from crossroads.rl.checkpoint import load_networks  # noqa: E402
from crossroads.rl.idc_model import IDCModel  # noqa: E402
from crossroads.sim.config import WorldConfig  # noqa: E402
from crossroads.sim.ego import ego_step  # noqa: E402
from crossroads.sim.traffic import NO_TRAFFIC  # noqa: E402
from crossroads.sim.world import World  # noqa: E402
from queue_response import standing_car_scene  # noqa: E402  (beside this script)

START_S_M = 20.0  # [m] the ego's position along the path


def trace(model: IDCModel, policy: torch.nn.Module, batch: StateBatch, steps: int, title: str) -> None:
    """Drive the one-cell ``batch`` in closed loop; every 4 steps print the state and the plan's J_safe."""
    leader = batch.others[:, 0, :2]
    ego = batch.ego
    print(f"\n{title}: closed loop, every 0.4 s")
    print(f"{'t [s]':>6}{'gap [m]':>9}{'v [m/s]':>9}{'a [m/s2]':>10}{'Δa':>7}{'plan J_safe':>13}")
    with torch.no_grad():
        for k in range(steps):
            now = StateBatch(ego, batch.others, batch.kappa, batch.path, batch.stop)
            u = policy.mean_action(model.initial_states(now))  # type: ignore[operator]
            if k % 4 == 0:
                plan = model.rollout(now, lambda s, i: policy.mean_action(s), None, HORIZON_T)  # type: ignore[operator]
                gap = float(torch.linalg.norm(ego[0, :2] - leader[0])) - 0.5 * (EGO_LENGTH_M + CAR_LENGTH_M)
                print(f"{k / 10:>6.1f}{gap:>9.1f}{float(ego[0, 2]):>9.2f}{float(ego[0, 7]):>10.2f}"
                      f"{float(u[0, 1]):>7.2f}{float(plan.j_safe[0]):>13.2f}")
            ego = ego_step(ego, u)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", action="append", required=True, help="a trained model (.pt); repeatable")
    parser.add_argument("--speeds", type=float, nargs="+", default=[2.0, 4.0, 6.0, 8.0], help="[m/s]")
    parser.add_argument("--gaps", type=float, nargs="+", default=[6.0, 10.0, 15.0, 20.0, 30.0],
                        help="[m] bumper to bumper")
    parser.add_argument("--tail", type=int, nargs="+", default=[0, 40], help="stopping-tail steps to price")
    parser.add_argument("--trace", type=float, nargs=2, metavar=("V", "D"),
                        help="drive this one cell in closed loop instead, with the first --tail")
    parser.add_argument("--steps", type=int, default=60, help="closed-loop steps of 0.1 s (--trace)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    with World(WorldConfig(net_file=catalogue.build("c_three_lane"), task="straight", demand=NO_TRAFFIC,
                           warmup_s=1.0)) as world:
        candidates = world.candidates
    cells = [tuple(args.trace)] if args.trace else [(v, d) for v in args.speeds for d in args.gaps]
    n = len(cells)
    ego, others = standing_car_scene(candidates[0], cells, START_S_M)
    batch = StateBatch(ego, others, torch.zeros(n, N_OTHERS), torch.zeros(n, dtype=torch.long),
                       torch.zeros(n, dtype=torch.bool))
    paths = path_tensors(candidates, dtype=torch.float32)
    brake = torch.tensor([[0.0, -JERK_MAX]]).expand(n, 2)
    coast = torch.zeros(n, 2)
    for policy_file in args.policy:
        networks, _ = load_networks(Path(policy_file))
        policy = networks.policy
        if args.trace:
            model = IDCModel(paths, braking_floor=True, preview=policy.preview, stopping_tail=args.tail[0])
            trace(model, policy, batch, args.steps, f"{policy_file}, stopping tail {args.tail[0]} steps")
            continue
        for tail in args.tail:
            model = IDCModel(paths, braking_floor=True, preview=policy.preview, stopping_tail=tail)
            with torch.no_grad():
                costs = [model.rollout(batch, act, None, HORIZON_T)
                         for act in (lambda s, i, p=policy: p.mean_action(s), lambda s, i: brake,
                                     lambda s, i: coast)]
            print(f"\n{policy_file}, stopping tail {tail} steps: J = J_track + {PENALTY_RHO:g} J_safe of each plan")
            print(f"{'v [m/s]':>8}{'d [m]':>7}{'policy':>10}{'(J_safe)':>10}{'brake':>10}{'coast':>10}  cheapest")
            asks_brake = 0
            for k, (v, d) in enumerate(cells):
                j = [float(c.j_track[k] + PENALTY_RHO * c.j_safe[k]) for c in costs]
                cheapest = ("policy", "brake", "coast")[int(np.argmin(j))]
                asks_brake += j[1] < j[0]
                print(f"{v:>8g}{d:>7g}{j[0]:>10.1f}{float(costs[0].j_safe[k]):>10.2f}{j[1]:>10.1f}{j[2]:>10.1f}  {cheapest}")
            print(f"braking costs less than the policy's plan in {asks_brake} of {n} cells")


if __name__ == "__main__":
    main()
