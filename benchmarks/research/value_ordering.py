"""Does the value network pick the path the training model rates best? (the online decision, SPEC §4)

    .venv/bin/python benchmarks/research/value_ordering.py scenarios/nominal/c_three_lane-left.yaml \
        --policy models/apg.pt [--runs 6] [--every 10]

Drives the scenario's first N seeded episodes with the model and, every ``--every`` steps, builds the
state of every candidate path (in the mode the light logic chose) and compares two ratings of each:
the value network's v_w(s, τ), which the online decision minimises, and J_track of the driving
policy's own 25-step plan on that path in the differentiable model (ξ ≡ 0), which v_w is trained to
regress. It prints how often the two pick the same path, the regret in J_track of the value
network's pick, the rank correlation, and how often a path with a lower J_safe than the picked one
was on offer (the paper's value network rates tracking only, so that is by design, but it says how
much safety the choice leaves on the table).
"""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

from crossroads.scenario.spec import load_scenario, run_seeds, to_world_config  # noqa: E402
from crossroads.idc.decision import IdcController  # noqa: E402
from crossroads.idc.state import path_tensors  # noqa: E402
from crossroads.rl.buffer import Samples, to_batch  # noqa: E402
from crossroads.rl.checkpoint import load_networks  # noqa: E402
from crossroads.rl.idc_model import IDCModel  # noqa: E402
from crossroads.idc.observed import observed_others  # noqa: E402
from crossroads.rl.sampler import as_sample  # noqa: E402
from crossroads.sim.world import World  # noqa: E402
from probing import HORIZON, model_parser, probed_states  # noqa: E402


def spearman(a: np.ndarray, b: np.ndarray) -> float:
    """Rank correlation of two ratings of the same paths (nan when either is constant)."""
    ra, rb = np.argsort(np.argsort(a)), np.argsort(np.argsort(b))
    if ra.std() == 0 or rb.std() == 0:
        return float("nan")
    return float(np.corrcoef(ra, rb)[0, 1])


def main() -> None:
    parser = model_parser(__doc__.splitlines()[0], runs=6)
    parser.add_argument("--every", type=int, default=10, help="steps between probed states")
    args = parser.parse_args()
    torch.set_num_threads(1)

    networks, _ = load_networks(Path(args.policy))
    controller = IdcController(networks.policy, networks.value, name=Path(args.policy).stem)
    spec = load_scenario(args.scenario)
    values: list[np.ndarray] = []  # per probed state: v_w of each path
    tracks: list[np.ndarray] = []  # J_track of the policy's plan on each path
    safes: list[np.ndarray] = []  # J_safe of the same plans
    with World(to_world_config(spec, args.scenario.parent)) as world:
        model = IDCModel(path_tensors(world.candidates, dtype=torch.float32), preview=controller.preview)
        n_paths = len(world.candidates)
        if n_paths < 2:
            raise SystemExit(f"{args.scenario}: one candidate path, so the value network has nothing to choose")
        for obs, decision in probed_states(world, controller, run_seeds(spec, args.runs), args.every):
            stop = decision.speed_mode == "stop"
            others, kappa = observed_others(obs)
            batch = to_batch(Samples.concat([as_sample(obs.ego, others, kappa, p, stop) for p in range(n_paths)]))
            with torch.no_grad():  # every path's state in one rollout, one row each
                rolled = model.rollout(batch, lambda s, _: controller.policy.mean_action(s), None, HORIZON)
            values.append(np.asarray(decision.path_values, dtype=np.float64))
            tracks.append(rolled.j_track.double().numpy())
            safes.append(rolled.j_safe.double().numpy())

    v, jt, js = np.stack(values), np.stack(tracks), np.stack(safes)
    picked = v.argmin(axis=1)
    rows = np.arange(len(v))
    best = jt.argmin(axis=1)
    regret = jt[rows, picked] - jt[rows, best]
    rho = np.array([spearman(v[i], jt[i]) for i in rows])
    safer = js.min(axis=1) < js[rows, picked] - 1e-6
    abs_err = np.abs(v - jt)
    print(f"policy {args.policy} on {args.scenario}: {len(v)} states of {args.runs} seeded runs, "
          f"every {args.every} steps, {v.shape[1]} candidate paths each")
    print(f"value network picks the path of least J_track:  {int((picked == best).sum())} of {len(v)} "
          f"({100.0 * np.mean(picked == best):.1f} %)")
    print(f"regret in J_track of its pick:                  median {np.median(regret):.2f}, "
          f"p90 {np.percentile(regret, 90):.2f}, max {regret.max():.2f} "
          f"(J_track of the best path: median {np.median(jt[rows, best]):.2f})")
    print(f"rank correlation v_w ~ J_track per state:       median {np.nanmedian(rho):.2f}")
    print(f"|v_w − J_track|:                                median {np.median(abs_err):.2f}, "
          f"p90 {np.percentile(abs_err, 90):.2f}")
    print(f"a path with lower J_safe than the pick existed: {int(safer.sum())} of {len(v)} states "
          f"(pick's J_safe > 0 in {int((js[rows, picked] > 0).sum())})")


if __name__ == "__main__":
    main()
