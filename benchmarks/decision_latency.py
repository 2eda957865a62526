"""Latency of one whole online IDC decision next to the forward pass of its networks alone.

    .venv/bin/python benchmarks/decision_latency.py [--checkpoint models/apg.pt] [--samples 2000]

Whole decision = the light logic + x_other selection + the state of every candidate path + their
normalisation (``network_input``, once for both networks) + the value network on the batch of
candidates + argmin + the policy's mean action for τ*.
Networks alone = the value network on the same batch, already normalised, + the policy on one of
its rows, nothing else: what the decision adds is the difference. Both on observations recorded
from a real episode (c_three_lane, left turn, paper traffic), one thread.
Targets: p99 of the whole decision ≤ 1 ms on this CPU, ≤ 2 ms with the shield (the paper: < 10 ms).
A third line times the same decision with the safety shield (``idc.shield``, ``--policy …+shield``,
not the paper's): the curvature of every perceived participant and the two 40-step backups on top.
Without --checkpoint, freshly initialised networks of the paper's size (5 × 256) are timed:
latency does not depend on the weights.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from crossroads.idc.decision import IdcController
from crossroads.idc.rule_based import RuleBasedController
from crossroads.idc.state import build_states, network_input, select_others
from crossroads.intersections import catalogue
from crossroads.rl.checkpoint import load_networks
from crossroads.rl.neural_nets import make_networks
from crossroads.sim.config import WorldConfig
from crossroads.sim.world import World


def recorded_observations(n: int, seed: int) -> list:
    """Observations of a real episode driven by the rule controller (varied traffic)."""
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left", warmup_s=60.0)
    out = []
    with World(config) as world:
        controller = RuleBasedController()
        obs = world.reset(seed)
        controller.reset(world.candidates)
        while len(out) < n:
            world.truth.participants.lane_id  # noqa: B018 (read now, in its step: the shield's curvatures need it later)
            out.append(obs)
            obs, outcome = world.step(controller.decide(obs).action)
            if outcome is not None:
                seed += 1
                obs = world.reset(seed)
                controller.reset(world.candidates)
        candidates = world.candidates
    return out, candidates


def percentiles(samples_s: list[float]) -> tuple[float, float, float]:
    ms = np.asarray(samples_s) * 1e3
    return float(np.percentile(ms, 50)), float(np.percentile(ms, 99)), float(ms.max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", default=None)
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--observations", type=int, default=400)
    parser.add_argument("--preview", action="store_true",
                        help="without --checkpoint: networks that read the path preview (TrainConfig.path_preview)")
    args = parser.parse_args()
    torch.set_num_threads(1)

    if args.checkpoint:
        networks, _ = load_networks(Path(args.checkpoint))
        controller = IdcController(networks.policy, networks.value, name=Path(args.checkpoint).stem)
    else:
        torch.manual_seed(0)
        nets = make_networks("apg", hidden_layers=5, hidden_units=256, preview=args.preview)
        controller = IdcController(nets.policy, nets.value)
    shielded = IdcController(controller.policy, controller.value, shield=True)
    observations, candidates = recorded_observations(args.observations, seed=0)
    controller.reset(candidates)
    shielded.reset(candidates)

    # what the networks alone see: the same batches the decision builds, normalised
    batches = []
    for obs in observations:
        others = select_others(obs.ego, obs.perceived.observations, obs.perceived.kinds)
        states = build_states(obs.ego, others, candidates, controller.speed_mode(obs), controller.preview)
        batches.append(network_input(torch.from_numpy(states).float(), controller.policy.preview,
                                     controller.policy.lead))

    def bare(batch: torch.Tensor) -> None:
        with torch.inference_mode():
            values = controller.value.value_of_input(batch)
            controller.policy.mean_action_of_input(batch[int(torch.argmin(values))][None])

    for i in range(200):  # warm-up: allocator, caches
        controller.decide(observations[i % len(observations)])
        shielded.decide(observations[i % len(observations)])
        bare(batches[i % len(batches)])
    whole, forward, guarded = [], [], []
    for i in range(args.samples):  # interleaved
        obs, batch = observations[i % len(observations)], batches[i % len(batches)]
        t0 = time.perf_counter()
        controller.decide(obs)
        t1 = time.perf_counter()
        bare(batch)
        t2 = time.perf_counter()
        shielded.decide(obs)
        t3 = time.perf_counter()
        whole.append(t1 - t0)
        forward.append(t2 - t1)
        guarded.append(t3 - t2)
    w50, w99, wmax = percentiles(whole)
    f50, f99, fmax = percentiles(forward)
    s50, s99, smax = percentiles(guarded)
    print(f"{len(candidates)} candidate paths, networks 5 x 256 GELU"
          f"{' with the path preview' if controller.preview else ''}, {args.samples} decisions, 1 thread")
    print(f"whole decision : p50 {w50:.3f} ms  p99 {w99:.3f} ms  max {wmax:.3f} ms")
    print(f"networks alone : p50 {f50:.3f} ms  p99 {f99:.3f} ms  max {fmax:.3f} ms")
    print(f"with the shield: p50 {s50:.3f} ms  p99 {s99:.3f} ms  max {smax:.3f} ms (not the paper's; +shield)")
    print(f"overhead p50   : {w50 - f50:.3f} ms ({w50 / f50:.2f} x the networks alone)")
    print(f"targets: p99 <= 1 ms {'met' if w99 <= 1.0 else 'NOT met'}; "
          f"with the shield p99 <= 2 ms {'met' if s99 <= 2.0 else 'NOT met'}")


if __name__ == "__main__":
    main()
