"""How strong an APG model's adversary is: can the driving policy escape it at all?

    .venv/bin/python benchmarks/research/adversary_strength.py scenarios/nominal/c_three_lane-left.yaml \
        --policy models/apg.pt [--runs 6] [--every 15]

Drives the scenario's first N seeded episodes with the model and, every ``--every`` steps, puts the
state through the training model (T = 25) three ways — the policy's own plan, full braking
(Δa = −JERK_MAX), full acceleration (Δa = +JERK_MAX) — each with ξ ≡ 0 and with the adversary's
mean ξ, and prints J_safe of all six. Training draws ξ from the adversary's Gaussian instead of
taking its mean (``sample_actions``), so the last line repeats the count with ξ drawn, the median
of ``--draws`` seeded draws per state and plan. A fair adversary leaves some plan with a low J_safe; when
J_safe stays high whatever the ego does (even standing still), the minimax game cannot be won and
the policy learns nothing about safety from it (ξ_x, ξ_y act as the training model has them: a
bounded offset of each predicted position, rl.idc_model). The last line gives the adversary's
mean ξ_v for participants standing just ahead of the ego against all others: an adversary that
speeds up a queue in front of the ego predicts a milder scene than ξ ≡ 0 (rl.idc_model, nominal floor).
"""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

from crossroads.constants import JERK_MAX, XI_RANGES  # noqa: E402
from crossroads.scenario.spec import load_scenario, run_seeds, to_world_config  # noqa: E402
from crossroads.idc.decision import IdcController  # noqa: E402
from crossroads.idc.state import PAD_DISTANCE_M, path_tensors  # noqa: E402
from crossroads.rl.buffer import Samples, to_batch  # noqa: E402
from crossroads.rl.checkpoint import load_networks  # noqa: E402
from crossroads.rl.idc_model import IDCModel  # noqa: E402
from crossroads.rl.sampler import observation_sample  # noqa: E402
from crossroads.sim.world import World  # noqa: E402
from probing import HORIZON, ego_frame, model_parser, probed_states  # noqa: E402

PLANS = (("plan", None), ("brake", -JERK_MAX), ("accelerate", JERK_MAX))
STANDING_MPS = 0.5
AHEAD_M = (0.0, 25.0)  # [m] "just ahead": longitudinally in this range of the ego's centre …
AHEAD_LATERAL_M = 2.0  # … and laterally within this


def standing_ahead(ego: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Mask over the participant slots ``others[16, 6]``: standing just ahead of the ego (its frame).
    (Padded slots lie ``PAD_DISTANCE_M`` behind the ego, never ahead.)"""
    along, across = ego_frame(ego, others[:, 0], others[:, 1])
    return (along > AHEAD_M[0]) & (along < AHEAD_M[1]) & (np.abs(across) < AHEAD_LATERAL_M) & \
        (others[:, 2] < STANDING_MPS)


def main() -> None:
    parser = model_parser(__doc__.splitlines()[0], runs=6)
    parser.add_argument("--every", type=int, default=15, help="steps between probed states")
    parser.add_argument("--draws", type=int, default=8, help="ξ draws per state and plan (median)")
    args = parser.parse_args()
    torch.set_num_threads(1)

    networks, _ = load_networks(Path(args.policy))
    if networks.adversary is None:
        parser.error(f"--policy: {args.policy} has no adversary (a DPG model?)")
    adversary = networks.adversary
    controller = IdcController(networks.policy, networks.value, name=Path(args.policy).stem)
    spec = load_scenario(args.scenario)
    rows: list[list[float]] = []  # per probed state: ξ≡0 then adversary, for each plan
    drawn: list[list[float]] = []  # per probed state: median J_safe with ξ drawn, for each plan
    speeds: list[float] = []
    xi_v_ahead: list[float] = []  # the adversary's mean ξ_v of each participant standing ahead
    xi_v_rest: list[float] = []  # … of every other real (not padded) participant
    generator = torch.Generator().manual_seed(0)
    with World(to_world_config(spec, args.scenario.parent)) as world:
        model = IDCModel(path_tensors(world.candidates, dtype=torch.float32), preview=controller.preview)
        for obs, decision in probed_states(world, controller, run_seeds(spec, args.runs), args.every):
            sample = observation_sample(obs, int(decision.path_index), decision.speed_mode == "stop")
            batch = to_batch(sample)
            with torch.no_grad():
                xi_v = adversary.mean_action(model.initial_states(batch))[0, :, 2].numpy()
            ahead = standing_ahead(sample.ego[0], sample.others[0])
            real = np.hypot(*(sample.others[0, :, :2] - sample.ego[0, :2]).T) < 0.5 * PAD_DISTANCE_M
            xi_v_ahead += xi_v[ahead & real].tolist()
            xi_v_rest += xi_v[~ahead & real].tolist()
            draws = to_batch(Samples.concat([sample] * args.draws))  # one row per draw, one rollout
            row, row_drawn = [], []
            for _, jerk in PLANS:
                def act(s: torch.Tensor, _: int, jerk: float | None = jerk) -> torch.Tensor:
                    u = controller.policy.mean_action(s)
                    return u if jerk is None else torch.stack([u[:, 0], torch.full_like(u[:, 1], jerk)], -1)
                with torch.no_grad():
                    row.append(float(model.rollout(batch, act, None, HORIZON).j_safe[0]))
                    row.append(float(model.rollout(batch, act, lambda s, _: adversary.mean_action(s),
                                                   HORIZON).j_safe[0]))
                    drawn_safe = model.rollout(draws, act, lambda s, _: adversary.sample(s, generator), HORIZON).j_safe
                    row_drawn.append(float(np.median(drawn_safe.numpy())))
            rows.append(row)
            drawn.append(row_drawn)
            speeds.append(float(obs.ego[2]))

    table = np.asarray(rows)
    speed = np.asarray(speeds)
    print(f"policy {args.policy} on {args.scenario}: "
          f"{len(rows)} states of {args.runs} seeded runs, every {args.every} steps")
    print(f"{'J_safe over 25 steps':<30}" + "".join(f"{name + ' ξ≡0':>16}{name + ' adv.':>16}" for name, _ in PLANS))
    for label, mask in (("all states", np.ones(len(speed), bool)), ("ego standing (< 0.5 m/s)", speed < 0.5),
                        ("ego moving", speed >= 0.5)):
        if not mask.any():
            continue
        print(f"{label + f' ({int(mask.sum())})':<30}" + "".join(f"{np.median(table[mask, k]):>16.1f}"
                                                                 for k in range(table.shape[1])))
    best_adv = table[:, 1::2].min(axis=1)
    print(f"states where no plan keeps J_safe < 1 against the adversary: {int((best_adv >= 1.0).sum())} of {len(rows)} "
          f"(with ξ ≡ 0: {int((table[:, 0::2].min(axis=1) >= 1.0).sum())})")
    sampled = np.asarray(drawn)
    moving = speed >= 0.5
    print(f"with ξ drawn as in training (median of {args.draws} draws): no plan keeps J_safe < 1 in "
          f"{int((sampled.min(axis=1) >= 1.0).sum())} of {len(rows)} states; median J_safe for a moving ego: "
          + ", ".join(f"{name} {np.median(sampled[moving, k]) if moving.any() else float('nan'):.1f}"
                      for k, (name, _) in enumerate(PLANS)))
    quartiles = lambda v: "n/a" if not v else "median {:.3f} (10-90 %: {:.3f}-{:.3f})".format(  # noqa: E731
        *np.percentile(v, [50, 10, 90]))
    print(f"the adversary's mean ξ_v [m/s per step, range {XI_RANGES['v'][0]}-{XI_RANGES['v'][1]}]: participants "
          f"standing ≤ {AHEAD_M[1]:g} m ahead of the ego ({len(xi_v_ahead)}) {quartiles(xi_v_ahead)}; "
          f"all others ({len(xi_v_rest)}) {quartiles(xi_v_rest)}")


if __name__ == "__main__":
    main()
