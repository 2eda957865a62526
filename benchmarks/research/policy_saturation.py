"""How saturated are a trained driving policy's outputs? Pre-tanh means on states of the sampler's world.

    .venv/bin/python benchmarks/research/policy_saturation.py --policy models/apg.pt --policy models/dpg.pt

The driving policy's action is tanh(z) mapped onto its range (``rl.neural_nets``). Past |z| ≈ 2.5 the
slope of tanh vanishes (1 − tanh²(3) = 0.01), so the model's gradient of J_π barely reaches such
an output any more: a policy whose outputs sit there has stopped learning from those states. The
states are those of the training sampler's world (``rl.sampler.EpisodeSampler``: random
intersection, task, candidate path, light phase, start and demand per round; the rule controller
drives, standing-car copies included), ``--rounds`` rounds from ``--seed``, the same for every
policy given. Printed per policy and output (Δδ, Δa): the median |z| and the shares of states with
|z| beyond 2.5 and 3, side by side.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

from crossroads.rl.buffer import Samples, to_batch  # noqa: E402
from crossroads.rl.checkpoint import load_networks  # noqa: E402
from crossroads.rl.config import TrainConfig  # noqa: E402
from crossroads.rl.idc_model import IDCModel  # noqa: E402
from crossroads.rl.sampler import EpisodeSampler, PathSet, WorkerSpec  # noqa: E402

BOUNDS = (2.5, 3.0)  # |z| thresholds printed (tanh 0.987 and 0.995 of the range)
OUTPUTS = ("Δδ", "Δa")


def sampled_states(rounds: int, seed: int) -> tuple[Samples, PathSet]:
    """The states of ``rounds`` rule-driven rounds of the training sampler (worker 0)."""
    config = TrainConfig(seed=seed, workers=0)
    paths = PathSet.build(config.intersections, config.tasks)
    sampler = EpisodeSampler(WorkerSpec(config, paths.keys), 0)
    return Samples.concat([sampler.round(r, None) for r in range(rounds)]), paths


def pre_squash_means(policy_file: Path, samples: Samples, paths: PathSet) -> np.ndarray:
    """z [N, 2]: the policy's pre-tanh means on the states."""
    networks, _ = load_networks(policy_file)
    model = IDCModel(paths.tensors(), preview=networks.policy.preview)
    with torch.no_grad():
        mean, _ = networks.policy.distribution(model.initial_states(to_batch(samples)))
    return mean.numpy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", action="append", type=Path, required=True, help="a trained model (.pt); repeat")
    parser.add_argument("--rounds", type=int, default=40, help="sampling rounds (one episode each)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    samples, paths = sampled_states(args.rounds, args.seed)
    print(f"{len(samples)} states from {args.rounds} rule-driven rounds of the training sampler (seed {args.seed})")
    header = f"{'policy':<40} {'output':<6} {'median |z|':>10}" + "".join(f" {f'|z|>{b}':>8}" for b in BOUNDS)
    print(header)
    for policy_file in args.policy:
        z = np.abs(pre_squash_means(policy_file, samples, paths))
        for j, name in enumerate(OUTPUTS):
            shares = "".join(f" {np.mean(z[:, j] > b):>8.1%}" for b in BOUNDS)
            print(f"{str(policy_file):<40} {name:<6} {np.median(z[:, j]):>10.2f}{shares}")


if __name__ == "__main__":
    main()
