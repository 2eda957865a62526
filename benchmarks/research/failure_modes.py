"""Why a trained policy fails: its collisions classified, and what its own model predicted before them.

    .venv/bin/python benchmarks/research/failure_modes.py scenarios/nominal/c_three_lane-left.yaml \
        --policy models/apg.pt [--runs 50]      (models/apg.pt+shield: with the safety shield)

Runs the scenario's first N seeded episodes (the seeds of ``crossroads evaluate``) with a trained
IDC policy and prints:

* the outcomes; each timeout by what held the ego at the end (``probing.timeout_cause``: a vehicle
  ahead standing ≥ 30 s, the world's gridlock no driver passes; a shorter queue; or where the ego
  stood and what was in its way), with how long the ego had stood;
* each collision by where the other participant was (front / side / rear of the
  ego, from its centre in the ego's frame) and whether it was standing (< 0.5 m/s), with the ego's
  speed at impact;
* for every collision, the state one second (``--look-back``) before impact put through the training model (the
  differentiable IDC model, T = 25 steps, ξ ≡ 0): J_safe of the policy's own plan (its mean action
  at every step) against J_safe of full braking (Δa = −JERK_MAX throughout);
* for an APG model, J_safe of the policy's plan from the same states with the adversary's mean ξ,
  as APG trained before the nominal floor (rl.idc_model): an adversary that predicts a milder scene
  than ξ ≡ 0 right before the collisions taught the policy that those scenes were safe.

* J_π of the policy's plan against the model's own open-loop optimum from the same states (Adam on
  the 25 actions, ``probing.open_loop_optimum``), and in how many of each the bodies' circles meet
  within the horizon; and whether the plan still meets the circles when every slot but the closest
  vehicle ahead is padded (is it the scene's clutter that hides the car ahead from the policy?).

When braking would have kept J_safe low and the policy's plan did not, the model saw the danger and
the policy did not act on it: a training problem, not a modelling one. When the optimum of the
model's cost itself collides, the cost or the model (its constant-velocity predictions, its circles)
is the suspect; when the optimum is safe and much cheaper than the plan, the policy is.
"""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

from crossroads.constants import CONGESTION_STOP_S, EGO_LENGTH_M, JERK_MAX, PENALTY_RHO  # noqa: E402
from crossroads.policy.ref import parse_policy  # noqa: E402
from crossroads.scenario.spec import load_scenario, run_seeds, to_world_config  # noqa: E402
from crossroads.idc.decision import IdcController  # noqa: E402
from crossroads.idc.state import pad_participant, path_tensors  # noqa: E402
from crossroads.rl.buffer import Samples, StateBatch, to_batch  # noqa: E402
from crossroads.rl.checkpoint import load_networks  # noqa: E402
from crossroads.rl.idc_model import IDCModel, Rollout  # noqa: E402
from crossroads.rl.neural_nets import Adversary  # noqa: E402
from crossroads.sim.world import World  # noqa: E402
from probing import (  # noqa: E402
    CORRIDOR_HALF_WIDTH_M,
    HORIZON,
    STANDING_MPS,
    ego_frame,
    episode_endings,
    model_parser,
    open_loop_optimum,
    timeout_cause,
    vehicle_ahead,
)

SIDE_BAND_M = 2.0  # |longitudinal offset| below this: the other is beside the ego


def where(ego: np.ndarray, x: float, y: float) -> str:
    """front / side / rear of the other's centre in the ego's frame."""
    ahead, _ = ego_frame(ego, x, y)
    return "front" if ahead > SIDE_BAND_M else ("rear" if ahead < -SIDE_BAND_M else "side")


def plans(model: IDCModel, controller: IdcController, batch: StateBatch,
          adversary: Adversary | None) -> tuple[Rollout, Rollout, Rollout | None]:
    """The rollouts from every state of ``batch`` of the policy's plan and of full braking with
    ξ ≡ 0, and of the policy's plan with the adversary's mean ξ (None without an adversary)."""
    own = lambda s, _: controller.policy.mean_action(s)  # noqa: E731
    brake = torch.tensor([[0.0, -JERK_MAX]], dtype=torch.float32)
    with torch.no_grad():
        plan = model.rollout(batch, own, None, HORIZON)
        stop = model.rollout(batch, lambda s, _: brake.expand(s.shape[0], 2), None, HORIZON)
        adversarial = (None if adversary is None else
                       model.rollout(batch, own, lambda s, _: adversary.mean_action(s), HORIZON))
    return plan, stop, adversarial


def print_optimum(model: IDCModel, controller: IdcController, seen: Samples, plan: Rollout,
                  look_back_s: float) -> None:
    """The policy's ``plan`` from the states ``seen`` against the model's own open-loop optimum:
    is the cost itself content with a collision (then the optimum overlaps too), or is the policy
    far from what its cost asks? Then the clutter test: the plan from the same states with only
    the closest vehicle ahead left."""
    best = open_loop_optimum(model, to_batch(seen))

    def j_pi(out: Rollout) -> np.ndarray:
        return (out.j_track + PENALTY_RHO * out.j_safe).numpy()

    simplified, ahead = closest_vehicle_ahead_only(seen)
    with torch.no_grad():
        alone = model.rollout(to_batch(simplified), lambda s, _: controller.policy.mean_action(s), None, HORIZON)
    ahead_t = torch.from_numpy(ahead)
    print(f"{look_back_s:g} s before impact, J_π over {HORIZON} steps: policy's plan median {np.median(j_pi(plan)):.1f}, "
          f"the model's open-loop optimum {np.median(j_pi(best)):.1f}; the bodies' circles meet within the "
          f"horizon in {int((plan.overlap_m > 0).sum())} of {len(seen.ego)} plans and {int((best.overlap_m > 0).sum())} "
          f"optima (optimum's closest approach: median {-np.median(best.overlap_m.numpy()):.2f} m between circles)")
    print(f"the {int(ahead.sum())} of those states with a vehicle ahead (|across| < {CORRIDOR_HALF_WIDTH_M:g} m), every "
          f"other slot padded: the policy's plan meets its circles in {int(((alone.overlap_m > 0) & ahead_t).sum())} "
          f"(as seen: {int(((plan.overlap_m > 0) & ahead_t).sum())})")


def closest_vehicle_ahead_only(sample: Samples) -> tuple[Samples, np.ndarray]:
    """``sample`` with every participant slot padded except the closest vehicle ahead of the ego
    within ``CORRIDOR_HALF_WIDTH_M`` of its axis, which moves to the first slot; and which rows had
    such a vehicle."""
    others = np.empty_like(sample.others)
    found = np.zeros(len(sample.ego), dtype=bool)
    for b, ego in enumerate(sample.ego.astype(np.float64)):
        others[b] = pad_participant(ego)
        k = vehicle_ahead(ego, sample.others[b].astype(np.float64))
        if k is not None:
            others[b, 0] = sample.others[b, k]
            found[b] = True
    return Samples(sample.ego, others, np.zeros_like(sample.kappa), sample.path, sample.stop), found


def ahead_summary(sample: Samples) -> str:
    """The vehicle ahead (closest within ``CORRIDOR_HALF_WIDTH_M`` of the ego's axis) in each state
    of ``sample``: how many stood, their bumper gaps and the ego's speeds (medians)."""
    gaps, speeds, standing = [], [], 0
    for ego, others in zip(sample.ego.astype(np.float64), sample.others.astype(np.float64), strict=True):
        k = vehicle_ahead(ego, others)
        if k is not None:
            along, _ = ego_frame(ego, others[k, 0], others[k, 1])
            gaps.append(float(along) - 0.5 * (float(others[k, 4]) + EGO_LENGTH_M))
            speeds.append(float(ego[2]))
            standing += int(others[k, 2] < STANDING_MPS)
    if not gaps:
        return "no vehicle ahead in any of them"
    return (f"a vehicle ahead in {len(gaps)} of {len(sample.ego)}, standing in {standing}; bumper gap median "
            f"{np.median(gaps):.1f} m, the ego's speed median {np.median(speeds):.1f} m/s")


def print_timeouts(held: dict[str, list[float]]) -> None:
    """The timeouts by what held the ego at the end, with how long the ego had stood (median)."""
    if not held:
        return
    print(f"timeouts ({sum(map(len, held.values()))}), by what held the ego at the end "
          "[runs, the ego had stood: median s]:")
    for cause, stood in sorted(held.items(), key=lambda item: -len(item[1])):
        print(f"  {cause:<64}{len(stood):>4}   {np.median(stood):5.1f}")


def main() -> None:
    parser = model_parser(__doc__.splitlines()[0], runs=50)
    parser.add_argument("--look-back", type=float, default=1.0, help="[s] before impact (≤ 5)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    look_back_steps = max(1, min(50, round(args.look_back / 0.1)))

    spec = load_scenario(args.scenario)
    ref = parse_policy(args.policy)  # models/apg.pt+shield: with the safety shield
    if ref.kind != "checkpoint":
        parser.error(f"--policy: a trained checkpoint (.pt), optionally +shield; got {args.policy!r}")
    checkpoint, shield = ref.target, ref.shield
    networks, _ = load_networks(Path(checkpoint))
    controller = IdcController(networks.policy, networks.value, name=Path(checkpoint).stem, shield=shield)
    outcomes: Counter[str] = Counter()
    kinds: Counter[str] = Counter()
    impact_speeds: list[float] = []
    modes: list[tuple[str, float]] = []  # (speed mode, vehicle ahead stood [s]) at the look-back
    looked_back: list[Samples] = []  # the state at the look-back of every collision
    held: dict[str, list[float]] = {}  # timeout cause → how long the ego had stood at the end [s]
    with World(to_world_config(spec, args.scenario.parent)) as world:
        model = IDCModel(path_tensors(world.candidates, dtype=torch.float32), preview=controller.preview)
        for end in episode_endings(world, controller, run_seeds(spec, args.runs), args.look_back):
            outcomes[end.outcome.kind] += 1
            if end.outcome.kind == "timeout":
                held.setdefault(timeout_cause(end.final, end.truth), []).append(end.ego_stood_s)
            if end.outcome.kind != "collision":
                continue
            snap = end.truth.participants
            row = list(snap.ids).index(end.outcome.detail.split()[-1])
            standing = "standing" if snap.speed[row] < STANDING_MPS else "moving"
            kinds[f"{where(end.final.ego, snap.x[row], snap.y[row])}, {standing} {snap.kind[row]}"] += 1
            impact_speeds.append(float(end.final.ego[2]))
            modes.append((end.mode, end.stood_s))
            looked_back.append(end.before)

    print(f"policy {args.policy} on {args.scenario} ({args.runs} seeded runs)")
    print("outcomes: " + ", ".join(f"{k} {v}" for k, v in outcomes.most_common()))
    print_timeouts(held)
    if not impact_speeds:
        return
    print(f"collisions ({len(impact_speeds)}), by the other participant's place and motion:")
    for kind, n in kinds.most_common():
        print(f"  {kind:<32}{n:>4}")
    speeds = np.asarray(impact_speeds)
    print(f"ego speed at impact [m/s]: median {np.median(speeds):.1f}, "
          f"25-75 % {np.percentile(speeds, 25):.1f}-{np.percentile(speeds, 75):.1f}")
    n_pass = sum(mode == "pass" for mode, _ in modes)
    fresh = sum(mode == "pass" and 0.0 < stood <= CONGESTION_STOP_S for mode, stood in modes)
    print(f"speed mode {look_back_steps / 10:g} s before impact: pass {n_pass}, stop {len(modes) - n_pass}; "
          f"in the pass mode behind a vehicle standing for at most the {CONGESTION_STOP_S:g} s before the "
          f"light logic stops: {fresh}")
    seen = Samples.concat(looked_back)
    print(f"{look_back_steps / 10:g} s before impact: " + ahead_summary(seen))
    plan, brake, adversarial = plans(model, controller, to_batch(seen), networks.adversary)
    plan_a, brake_a = plan.j_safe.numpy(), brake.j_safe.numpy()
    print(f"{look_back_steps / 10:g} s before impact, the model's J_safe over {HORIZON} steps: policy's plan median "
          f"{np.median(plan_a):.1f}, full braking median {np.median(brake_a):.1f}; braking predicted "
          f"safer in {int((brake_a < plan_a).sum())} of {len(plan_a)} "
          f"(J_safe < 1 with braking in {int((brake_a < 1.0).sum())})")
    print_optimum(model, controller, seen, plan, look_back_steps / 10)
    if adversarial is not None:
        adv_a = adversarial.j_safe.numpy()
        print(f"the same states with the adversary's mean ξ (the scene APG trained on before the nominal floor): "
              f"policy's plan median {np.median(adv_a):.1f}; milder than ξ ≡ 0 in {int((adv_a < plan_a).sum())} "
              f"of {len(adv_a)}, harsher in {int((adv_a > plan_a).sum())}")


if __name__ == "__main__":
    main()
