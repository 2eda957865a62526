"""Does a trained policy stop behind a standing queue? A closed loop in the model, no SUMO traffic.

    .venv/bin/python benchmarks/research/queue_response.py --policy models/apg.pt [--policy models/dpg.pt]

The failure the models share (docs/tried/training.md) is driving into a vehicle
that stands in front of the ego. This isolates it: on a straight candidate path of an intersection
(default c_three_lane) the ego starts at speed v, a car (5.0 × 1.8 m) stands on the path a bumper
gap d ahead, every other slot of the state is a padded (virtual) participant, and the policy's mean
action drives the ego through f_ego for ``--steps`` steps (8 s), the state rebuilt every step as the
online decision builds it, in the pass mode (the reference wants the profile's speed: only the
policy's view of the car can stop the ego). Every (v, d) cell runs in one batch.

Printed per policy: the smallest bumper gap reached in each cell ("hit" when the footprints would
have met, i.e. the gap went below 0), the distance full braking needs from each speed (Δa = −4.5
m/s³ from a = 0, then a = −3 m/s²), so the cells a driver could still have stopped in are known,
and the speed the ego holds after 8 s on the same road with nobody there (the pass profile wants
8.33 m/s before the junction).
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

from crossroads.constants import EGO_LENGTH_M  # noqa: E402
from crossroads.idc.state import N_OTHERS, pad_participant, path_tensors  # noqa: E402
from crossroads.intersections import catalogue  # noqa: E402
from crossroads.planning.routes import CandidatePath  # noqa: E402
from crossroads.rl.augment import CAR_LENGTH_M, CAR_WIDTH_M  # noqa: E402  (the training copies' car)
from crossroads.rl.checkpoint import load_networks  # noqa: E402
from crossroads.rl.idc_model import IDCModel, assemble  # noqa: E402
from crossroads.sim.config import WorldConfig  # noqa: E402
from crossroads.sim.ego import braking_distance_m, ego_step  # noqa: E402
from crossroads.sim.traffic import NO_TRAFFIC  # noqa: E402
from crossroads.sim.world import World  # noqa: E402

START_S_M = 5.0  # [m] the ego's start along the path


def standing_car_scene(path: CandidatePath, cells: list[tuple[float, float]],
                       start_s_m: float) -> tuple[torch.Tensor, torch.Tensor]:
    """(ego [n, 8], others [n, 16, 6]) float32, one row per (v, d) cell: the ego ``start_s_m`` along
    ``path`` at speed v, a car standing on the path d m ahead bumper to bumper (none for d = inf),
    every other slot padded."""
    egos, blocks = [], []
    for v, gap in cells:
        x, y, heading, _ = path.reference_at(start_s_m)
        ego = np.array([x, y, v, 0.0, heading, 0.0, 0.0, 0.0])
        block = np.tile(pad_participant(ego), (N_OTHERS, 1))
        if math.isfinite(gap):
            cx, cy, ch, _ = path.reference_at(start_s_m + gap + 0.5 * (EGO_LENGTH_M + CAR_LENGTH_M))
            block[0] = [cx, cy, 0.0, ch, CAR_LENGTH_M, CAR_WIDTH_M]
        egos.append(ego)
        blocks.append(block)
    return (torch.tensor(np.asarray(egos), dtype=torch.float32),
            torch.tensor(np.asarray(blocks), dtype=torch.float32))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", action="append", required=True, help="a trained model (.pt); repeatable")
    parser.add_argument("--intersection", default="c_three_lane")
    parser.add_argument("--speeds", type=float, nargs="+", default=[2.0, 4.0, 6.0, 8.0], help="[m/s]")
    parser.add_argument("--gaps", type=float, nargs="+", default=[3.0, 6.0, 10.0, 15.0, 20.0, 30.0],
                        help="[m] bumper to bumper")
    parser.add_argument("--steps", type=int, default=80, help="closed-loop steps of 0.1 s")
    args = parser.parse_args()
    torch.set_num_threads(1)

    config = WorldConfig(net_file=catalogue.build(args.intersection), task="straight", demand=NO_TRAFFIC, warmup_s=1.0)
    with World(config) as world:
        candidates = world.candidates
    path = candidates[0]
    model = IDCModel(path_tensors(candidates, dtype=torch.float32))

    cells = [(v, d) for v in args.speeds for d in args.gaps] + [(v, math.inf) for v in args.speeds]
    ego_t, others_t = standing_car_scene(path, cells, START_S_M)
    n = len(cells)
    path_index = torch.zeros(n, dtype=torch.int64)
    stop = torch.zeros(n, dtype=torch.bool)
    leader = others_t[:, 0, :2]
    has_leader = torch.tensor([math.isfinite(g) for _, g in cells])

    print(f"{args.intersection} {path.id}: a car standing d m ahead (bumper to bumper), the ego at v, "
          f"pass mode, {args.steps / 10:g} s closed loop in the model; cells: smallest gap [m] or 'hit'")
    stopping = {v: float(braking_distance_m(v)) for v in args.speeds}
    print("full braking needs: " + ", ".join(f"{d:.1f} m from {v:g} m/s" for v, d in stopping.items()))
    for policy_file in args.policy:
        networks, _ = load_networks(Path(policy_file))
        model.preview = networks.policy.preview  # the states its networks read
        ego = ego_t.clone()
        min_gap = torch.full((n,), math.inf)
        with torch.no_grad():
            for _ in range(args.steps):
                x_track, ref = model.track(ego, path_index, stop)
                state = assemble(ego, x_track, others_t, model.preview_of(ego, ref, path_index, stop))
                ego = ego_step(ego, networks.policy.mean_action(state))
                gap = torch.linalg.norm(ego[:, :2] - leader, dim=-1) - 0.5 * (EGO_LENGTH_M + CAR_LENGTH_M)
                min_gap = torch.where(has_leader, torch.minimum(min_gap, gap), min_gap)
        table = {cell: (float(g), float(e[2])) for cell, g, e in zip(cells, min_gap, ego)}
        print(f"\n{policy_file}")
        print(f"{'v [m/s] / d [m]':<16}" + "".join(f"{d:>8g}" for d in args.gaps) + f"{'empty road: v after':>24}")
        hits = 0
        for v in args.speeds:
            row = []
            for d in args.gaps:
                g = table[(v, d)][0]
                hits += g < 0.0
                row.append(f"{'hit' if g < 0.0 else f'{g:.1f}':>8}")
            print(f"{v:<16g}" + "".join(row) + f"{table[(v, math.inf)][1]:>22.2f} m/s")
        avoidable = [(v, d) for v in args.speeds for d in args.gaps if d > stopping[v]]
        avoidable_hits = sum(table[c][0] < 0.0 for c in avoidable)
        print(f"hit in {hits} of {len(args.speeds) * len(args.gaps)} cells; in {avoidable_hits} of the "
              f"{len(avoidable)} where full braking would have stopped in time")


if __name__ == "__main__":
    main()
