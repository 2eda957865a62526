"""DAgger on the training model's own optimum: does the driving policy learn what its model knows?

    .venv/bin/python benchmarks/research/dagger.py models/apg.pt -o var/dagger/apg.pt \
        [--rounds 3] [--episodes 40] [--label-steps 60] [--fit-steps 600] [--seed 7]

Why: from the states 2 s before the shipped APG's collisions, the training model's own open-loop
optimum was safe in 36 of 37 (docs/tried/training.md, "The policy, not the cost"), and with the
braking floor its receding-horizon optimum stopped colliding on the seeds tried. The policy gradient
does not take the policy there. Plain imitation of the optimum on the training distribution
compounds errors on the states the imitator itself reaches; DAgger (Ross et al., 2011) labels the
states the current policy visits, aggregates them, and refits:

1. drive sampling episodes of the source's training distribution (``rl.sampler``: its
   intersections, tasks, traffic and exploration noise) with the current policy;
2. label every ``--stride``-th state with the first action of the training model's open-loop optimum
   there (Adam on the T actions of that state alone, from the policy's own plan, ξ ≡ 0, the braking
   floor on: every safety constraint also holds if each participant brakes to a stand);
3. fit the policy's mean (before tanh) to the aggregated labels (MSE), and go on with the next round.

The value network and the adversary are kept. Prints, per round, how far the policy's first action
was from its label and how much the optimum saved against the policy's plan (J_π of the rollouts),
and writes the model file (checkpoint format, with the source's lineage) to ``-o``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import torch
from torch import Tensor

from crossroads.constants import PENALTY_RHO
from crossroads.rl.buffer import Samples, to_batch
from crossroads.rl.checkpoint import load_networks
from crossroads.rl.distill import collect_episodes
from crossroads.rl.export import write_refitted_model
from crossroads.rl.idc_model import IDCModel
from crossroads.rl.sampler import PathSet

from imitation import Z_LIMIT, fit_mean
from probing import ACTION_SCALE, optimise_plans, policy_plan


def label(model: IDCModel, policy: torch.nn.Module, samples: Samples, horizon: int, steps: int,
          chunk: int = 1024) -> tuple[Tensor, Tensor, dict[str, float]]:
    """(s_0 (n, width), the optimum's first action before tanh (n, 2), figures) for ``samples``."""
    states, targets, j_policy, j_best, first_policy = [], [], [], [], []
    for start in range(0, len(samples), chunk):
        batch = to_batch(samples.take(slice(start, start + chunk)))
        raw, plan = policy_plan(model, policy, batch, horizon)
        j_pi = plan.j_track + PENALTY_RHO * plan.j_safe
        best_raw, best = optimise_plans(model, batch, raw, steps)
        states.append(best.s0)
        targets.append(best_raw[:, 0].clamp(-Z_LIMIT, Z_LIMIT))
        first_policy.append(raw[:, 0])
        j_policy.append(j_pi)
        j_best.append(best.j_track + PENALTY_RHO * best.j_safe)
    s0, z = torch.cat(states), torch.cat(targets)
    scale = ACTION_SCALE.to(z.dtype)
    gap = (torch.tanh(torch.cat(first_policy)) - torch.tanh(z)).abs() * scale
    jp, jb = torch.cat(j_policy), torch.cat(j_best)
    figures = {"states": float(len(s0)), "steer_gap": float(gap[:, 0].mean()), "jerk_gap": float(gap[:, 1].mean()),
               "j_policy_median": float(jp.median()), "j_optimum_median": float(jb.median()),
               "optimum_better_share": float((jb < jp).double().mean())}
    return s0, z, figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", type=Path)
    parser.add_argument("-o", "--out", type=Path, required=True)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--episodes", type=int, default=40, help="sampling episodes per round")
    parser.add_argument("--stride", type=int, default=2, help="label every N-th state of an episode")
    parser.add_argument("--label-steps", type=int, default=60, help="Adam steps of each state's optimum")
    parser.add_argument("--fit-steps", type=int, default=600, help="Adam steps of the fit, per round")
    parser.add_argument("--lr", type=float, default=1e-4)
    parser.add_argument("--batch-size", type=int, default=256)
    parser.add_argument("--seed", type=int, default=7, help="sampling seed (the training runs used 0)")
    args = parser.parse_args()

    started = time.monotonic()
    torch.manual_seed(args.seed)
    nets, config = load_networks(args.source)
    paths = PathSet.build(config.intersections, config.tasks)
    model = IDCModel(paths.tensors(dtype=torch.float32), braking_floor=True, preview=config.path_preview)
    generator = torch.Generator().manual_seed(args.seed)
    all_states: list[Tensor] = []
    all_z: list[Tensor] = []
    notes = []
    for r in range(args.rounds):
        t0 = time.monotonic()
        round_config = dataclasses.replace(config, seed=args.seed * 1000 + r)
        episodes = collect_episodes(round_config, paths, nets, args.episodes)
        samples = Samples.concat([e.take(slice(0, None, args.stride)) for e in episodes])
        t1 = time.monotonic()
        s0, z, figures = label(model, nets.policy, samples, config.horizon, args.label_steps)
        t2 = time.monotonic()
        all_states.append(s0)
        all_z.append(z)
        loss = fit_mean(nets.policy, torch.cat(all_states), torch.cat(all_z), args.fit_steps, args.lr, args.batch_size,
                        generator)
        line = (f"round {r}: {int(figures['states'])} states ({t1 - t0:.0f} s sampling, {t2 - t1:.0f} s labelling); "
                f"policy vs label |Δ| steer {figures['steer_gap']:.3f} rad/s, jerk {figures['jerk_gap']:.2f} m/s³; "
                f"J_π median policy {figures['j_policy_median']:.2f}, optimum {figures['j_optimum_median']:.2f} "
                f"(optimum better in {100 * figures['optimum_better_share']:.0f} %); fit loss {loss:.4f}")
        print(line, flush=True)
        notes.append(line)
        write_refitted_model(args.out, config, nets, args.source,
                             [f"DAgger on the model's optimum from {args.source}"] + notes, time.monotonic() - started)
    print(f"wrote {args.out} ({time.monotonic() - started:.0f} s)")


if __name__ == "__main__":
    main()
