"""Can the learner fix a policy's failures when it trains on them? A focused-training probe.

    .venv/bin/python benchmarks/research/focused_training.py scenarios/nominal/c_three_lane-left.yaml \
        --policy models/dpg.pt [--runs 20] [--steps 300] [--last 25] [--hot-share 0.5]

Drives the scenario's first ``--runs`` seeded episodes with the policy and keeps every state the
policy saw (the same rows the training sampler stores). Then, from the policy's own weights, it
takes ``--steps`` value and policy steps of Algorithm 1 (the model and the learner of training,
ξ ≡ 0) on batches of those states: uniform over all of them, except that a ``--hot-share`` of each
batch comes from the last ``--last`` states before each collision. Finally it drives the same seeds
and as many new ones again and prints the outcomes before and after.

What the answers mean: if the outcomes of the training seeds do not improve, the learner cannot
fit these states (an optimisation or model problem); if they improve only with a large hot share,
the states that matter are too rare in uniform draws (a sampling problem: see ``danger_share`` in
``crossroads train options``).
"""

from __future__ import annotations

import argparse
import os
from collections import Counter
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import torch  # noqa: E402

from crossroads.scenario.spec import ScenarioSpec, load_scenario, run_seeds, to_world_config  # noqa: E402
from crossroads.idc.decision import IdcController  # noqa: E402
from crossroads.rl.buffer import ReplayBuffer, Samples, StateBatch, to_batch  # noqa: E402
from crossroads.rl.checkpoint import load_networks  # noqa: E402
from crossroads.rl.learner import Learner  # noqa: E402
from crossroads.rl.idc_model import IDCModel  # noqa: E402
from crossroads.rl.sampler import PathSet, observation_sample  # noqa: E402
from crossroads.sim.world import World  # noqa: E402

BATCH = 256


def drive(spec: ScenarioSpec, base_dir: Path, controller: IdcController, seeds: list[int],
          path_keys: dict[tuple[str, str, int], int], last: int) -> tuple[Counter[str], Samples, Samples]:
    """Outcomes, every state seen, and the last ``last`` states of each collision episode."""
    outcomes: Counter[str] = Counter()
    every: list[Samples] = []
    hot: list[Samples] = []
    name = str(spec.intersection)
    with World(to_world_config(spec, base_dir)) as world:
        for seed in seeds:
            obs = world.reset(seed)
            controller.reset(world.candidates)
            rows: list[Samples] = []
            outcome = None
            while outcome is None:
                decision = controller.decide(obs)
                key = path_keys[(name, spec.task, int(decision.path_index))]
                rows.append(observation_sample(obs, key, decision.speed_mode == "stop"))
                obs, outcome = world.step(decision.action)
            outcomes[outcome.kind] += 1
            every += rows
            if outcome.kind == "collision":
                hot += rows[-last:]
    return outcomes, Samples.concat(every), Samples.concat(hot)


def show(label: str, outcomes: Counter[str]) -> None:
    print(f"{label:<34}" + ", ".join(f"{k} {v}" for k, v in outcomes.most_common()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", type=Path)
    parser.add_argument("--policy", required=True)
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--last", type=int, default=25, help="states before a collision (0.1 s each)")
    parser.add_argument("--hot-share", type=float, default=0.0)
    parser.add_argument("--lr", type=float, default=3e-4)
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(0)

    spec = load_scenario(args.scenario)
    if not isinstance(spec.intersection, str):
        raise SystemExit("focused_training: the scenario must name a catalogue intersection")
    networks, config = load_networks(Path(args.policy))
    config = replace(config, algo="dpg", iterations=args.steps, policy_lr=(args.lr, args.lr / 30),
                     value_lr=(args.lr, args.lr / 30), max_grad_norm=10.0)
    paths = PathSet.build(config.intersections, config.tasks)
    keys = paths.index()
    seeds = run_seeds(spec, 2 * args.runs)
    train_seeds, new_seeds = seeds[: args.runs], seeds[args.runs:]

    before, every, hot = drive(spec, args.scenario.parent, IdcController(networks.policy, networks.value),
                               train_seeds, keys, args.last)
    show("before, training seeds:", before)
    print(f"states: {len(every)} seen, {len(hot)} in the last {args.last / 10:g} s before a collision")

    learner = Learner(config, IDCModel(paths.tensors(), preview=config.path_preview))
    learner.nets.policy.load_state_dict(networks.policy.state_dict())
    learner.nets.value.load_state_dict(networks.value.state_dict())
    uniform, danger = ReplayBuffer(len(every), seed=0), ReplayBuffer(max(len(hot), 1), seed=1)
    uniform.add(every)
    danger.add(hot)
    n_hot = int(round(BATCH * args.hot_share)) if len(hot) else 0
    for k in range(args.steps):
        parts = [uniform.sample(BATCH - n_hot)] + ([danger.sample(n_hot)] if n_hot else [])
        batch = StateBatch(*(torch.cat(tensors) for tensors in zip(*parts, strict=True)))
        losses = learner.update(batch, k)
        if (k + 1) % 50 == 0 or k + 1 == args.steps:
            with torch.no_grad():
                on_hot = learner.rollout(to_batch(hot), sample=False).j_safe.mean() if len(hot) else float("nan")
            print(f"step {k + 1:>4}: J_track {losses.j_track:7.2f}  J_safe {losses.j_safe:7.2f}  "
                  f"J_safe on the pre-collision states {float(on_hot):7.2f}", flush=True)

    trained = IdcController(learner.nets.policy, learner.nets.value)
    show("after, training seeds:", drive(spec, args.scenario.parent, trained, train_seeds, keys, args.last)[0])
    show("after, new seeds:", drive(spec, args.scenario.parent, trained, new_seeds, keys, args.last)[0])


if __name__ == "__main__":
    main()
