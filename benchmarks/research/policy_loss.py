"""Which states does a policy step improve? The paper's mean J_π against the other ``policy_loss`` variants.

    .venv/bin/python benchmarks/research/policy_loss.py --policy models/apg.pt [--steps 150] [--rounds 30]

From the checkpoint's networks, each variant of ``TrainConfig.policy_loss`` (mean, sqrt, log) takes ``--steps``
iterations of Algorithm 1 (the learner of training: value, policy and adversary steps, Adam, the
given learning rates) on the same buffer of states: ``--rounds`` rule-driven rounds of the training
sampler (``rl.sampler.EpisodeSampler``, seeded), scored by the policy's plan and drawn with the
default ``danger_share`` (half of each batch among the states whose plan had J_safe > 1), exactly as
in training, from the same first draws for every variant. Every ``--every`` steps it prints, for the
policy's mean plan under the model (ξ ≡ 0, T = 25):

* J_π, J_track, J_safe and the share of plans whose circles meet, over 512 fixed states drawn
  uniformly from the buffer and over 512 of its dangerous ones (J_safe > 1 at the start);
* on an empty straight road (c_three_lane, straight-0, 50 m before the stop line, pass mode) starting
  at 3 m/s and at the reference 8.33 m/s: the policy's first Δa and the J_track of its plan, next to
  the model's open-loop optimum (``probing.open_loop_optimum``).

What it showed: docs/tried/training.md, "Which states the policy's step serves".
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from probing import open_loop_optimum  # noqa: E402

from crossroads.constants import PENALTY_RHO  # noqa: E402
from crossroads.idc.observed import observed_others  # noqa: E402
from crossroads.rl.buffer import ReplayBuffer, Samples, StateBatch, to_batch  # noqa: E402
from crossroads.rl.config import TrainConfig  # noqa: E402
from crossroads.rl.learner import Learner  # noqa: E402
from crossroads.rl.idc_model import IDCModel, policy_fns  # noqa: E402
from crossroads.rl.sampler import EpisodeSampler, PathSet, WorkerSpec, as_sample, net_file  # noqa: E402
from crossroads.rl.train import warm_start  # noqa: E402
from crossroads.sim.config import EgoStart, WorldConfig  # noqa: E402
from crossroads.sim.traffic import NO_TRAFFIC  # noqa: E402
from crossroads.sim.world import World  # noqa: E402

EVAL_STATES = 512
PROBE_SPEEDS = (3.0, 8.33)  # [m/s] empty-road starts: below and at the pass profile's speed
PROBE = ("c_three_lane", "straight", 0)


def empty_road_states(paths: PathSet) -> list[StateBatch]:
    """One state per probe speed: the ego alone, 50 m before the stop line, green (pass mode)."""
    key = paths.index()[PROBE]
    out = []
    for speed in PROBE_SPEEDS:
        start = EgoStart(distance_to_stop_line_m=50.0, speed_mps=speed)
        with World(WorldConfig(net_file=net_file(PROBE[0]), task=PROBE[1], ego_start=start,
                               demand=NO_TRAFFIC)) as world:  # type: ignore[arg-type]
            obs = world.reset(1)
            others, kappa = observed_others(obs)
            out.append(to_batch(as_sample(obs.ego, others, kappa, key, False)))
    return out


def plan_figures(learner: Learner, batch: StateBatch) -> tuple[float, float, float, float]:
    """(J_π, J_track, J_safe, share of plans whose circles meet) of the policy's mean plans."""
    act, _ = policy_fns(learner.nets.policy, None, False)
    with torch.no_grad():
        out = learner.model.rollout(batch, act, None, learner.config.horizon)
    j_pi = out.j_track + PENALTY_RHO * out.j_safe
    return (float(j_pi.mean()), float(out.j_track.mean()), float(out.j_safe.mean()),
            float((out.overlap_m > 0).float().mean()))


def first_action_and_cost(learner: Learner, batch: StateBatch) -> tuple[float, float]:
    act, _ = policy_fns(learner.nets.policy, None, False)
    with torch.no_grad():
        u = learner.nets.policy.mean_action(learner.model.initial_states(batch))[0]
        out = learner.model.rollout(batch, act, None, learner.config.horizon)
    return float(u[1]), float(out.j_track[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", type=Path, required=True, help="an APG checkpoint or model (.pt)")
    parser.add_argument("--steps", type=int, default=150)
    parser.add_argument("--every", type=int, default=50)
    parser.add_argument("--rounds", type=int, default=30, help="sampling rounds (one episode each)")
    parser.add_argument("--lr", type=float, default=1e-4, help="policy and value learning rate")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--losses", nargs="+", default=["mean", "sqrt", "log"], help="policy_loss variants")
    args = parser.parse_args()
    torch.set_num_threads(1)

    base = TrainConfig(workers=0, seed=args.seed, iterations=10 * args.steps, policy_lr=(args.lr, args.lr),
                       value_lr=(args.lr, args.lr), adversary_lr=(args.lr / 3, args.lr / 3))
    paths = PathSet.build(base.intersections, base.tasks)
    sampler = EpisodeSampler(WorkerSpec(base, paths.keys), 0)
    samples = Samples.concat([sampler.round(r, None) for r in range(args.rounds)])
    model = IDCModel(paths.tensors(), nominal_floor=base.nominal_floor)
    probes = empty_road_states(paths)
    optima = [float(open_loop_optimum(model, b).j_track[0]) for b in probes]

    scorer = Learner(base, model)
    warm_start(scorer, args.policy)
    danger = np.concatenate([scorer.danger(to_batch(Samples(*(f[i:i + 1024] for f in samples))))
                             for i in range(0, len(samples), 1024)])
    rng = np.random.default_rng(args.seed)
    uniform = rng.choice(len(samples), EVAL_STATES, replace=False)
    hot_all = np.flatnonzero(danger > base.danger_threshold)
    hot = rng.choice(hot_all, min(EVAL_STATES, len(hot_all)), replace=False)
    print(f"{len(samples)} states from {args.rounds} rule-driven rounds, {len(hot_all)} dangerous "
          f"(J_safe > {base.danger_threshold}); the model's optimum on the empty road: J_track "
          + ", ".join(f"{o:.1f} from {v} m/s" for o, v in zip(optima, PROBE_SPEEDS)))
    group = f"{'J_pi':>7} {'J_track':>8} {'J_safe':>7} {'meet':>5}"
    print(f"{'':<11} | {'uniform states':^30} | {'dangerous states':^30} | "
          + " | ".join(f"{f'empty road from {v} m/s':^21}" for v in PROBE_SPEEDS))
    print(f"{'loss':<5} {'step':>5} | {group} | {group} | " + " | ".join(f"{'Δa':>10} {'J_track':>10}" for _ in PROBE_SPEEDS))
    for loss in args.losses:
        torch.manual_seed(args.seed)
        learner = Learner(replace(base, policy_loss=loss), model)
        warm_start(learner, args.policy)
        buffer = ReplayBuffer(len(samples), np.random.SeedSequence(args.seed))
        buffer.add(samples, danger)
        eval_sets = [buffer.batch(uniform), buffer.batch(hot)]
        for step in range(args.steps + 1):
            if step % args.every == 0:
                cells = [" ".join(f"{x:>{w}.{p}f}" for x, w, p in zip(plan_figures(learner, b), (7, 8, 7, 5),
                                                                        (1, 1, 2, 2)))
                         for b in eval_sets]
                probe = " | ".join("{:>+10.2f} {:>10.1f}".format(*first_action_and_cost(learner, b)) for b in probes)
                print(f"{loss:<5} {step:>5} | {cells[0]} | {cells[1]} | {probe}", flush=True)
            if step == args.steps:
                break
            drawn = buffer.draw(base.batch_size, base.danger_share, base.danger_threshold)
            losses = learner.update(buffer.batch(drawn), step)
            buffer.rescore(drawn, losses.j_safe_per_state)


if __name__ == "__main__":
    main()
