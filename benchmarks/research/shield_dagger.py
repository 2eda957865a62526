"""DAgger with the shielded APG (or the rule controller's braking) as the expert: can the bare
policy learn what the shield adds?

    .venv/bin/python benchmarks/research/shield_dagger.py models/apg.pt -o var/shield-dagger/apg.pt \
        [--rounds 3] [--seeds 2] [--fit-steps 1500] [--base-seed 7] [--expert shield|rule]

Why: with the safety shield the shipped APG passes 72–90 % of the paper's cases, bare 18–32 %
(docs/results/). The shield's labels cost one shielded decision (~2.5 ms) a state, where the
training model's optimum costs ~0.5 s (``dagger.py``), so the bare policy can be taught on the
evaluation's own scenes. Round 0 lets the expert (the model with ``+shield``) drive; every later
round the bare student drives and the expert labels the states it reaches (DAgger). Each state's
label is the expert's command (the policy's action, or the shield's braking); the student's
input is the bare decision's state of the path the value network picks (the student keeps the
value network, so it picks the same path). The student's mean before tanh is fitted to the
labels (MSE, all rounds' states). Scenes: every nominal and paper scenario, ``--seeds`` runs each
from ``--base-seed`` (the evaluations use 20261206 and the scenarios' own 0), 60 s episodes.

``--expert rule``: the label's steering is the bare source policy's (its tracking is what the
paper's training gives, 0.11 m on the straights), its jerk the rule controller's, which yields to
anyone on or heading for its path and passes about 95 % of the nominal left turns on
``c_three_lane`` where the APG passes about 31 % (docs/results/world.md): only the longitudinal decision is taught.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch

from crossroads.constants import JERK_MAX, STEER_RATE_MAX
from crossroads.idc.controller import Decision
from crossroads.idc.decision import IdcController
from crossroads.idc.rule_based import RuleBasedController
from crossroads.idc.state import build_states, select_others
from crossroads.planning import CandidatePath
from crossroads.rl.checkpoint import load_networks
from crossroads.rl.export import write_refitted_model
from crossroads.scenario.spec import load_scenario, run_seeds, to_world_config
from crossroads.sim.observation import Observation
from crossroads.sim.world import World

from imitation import Z_LIMIT, fit_mean

REPO = Path(__file__).resolve().parents[2]
SCALE = np.array([STEER_RATE_MAX, JERK_MAX])


def scenes(seeds: int, base_seed: int) -> list[tuple[Path, int]]:
    """(scenario file, seed) of every nominal and paper scenario, ``seeds`` runs each."""
    out = []
    for path in sorted((REPO / "scenarios/nominal").glob("*.yaml")) + sorted((REPO / "scenarios/paper").glob("*.yaml")):
        spec = load_scenario(path).model_copy(update={"seed": base_seed})
        out += [(path, s) for s in run_seeds(spec, seeds)]
    return out


class RuleBrakingExpert:
    """The bare policy's path and steering with the rule controller's jerk (``--expert rule``)."""

    def __init__(self, policy: IdcController) -> None:
        self.policy = policy
        self.rule = RuleBasedController()

    def reset(self, candidates: Sequence[CandidatePath]) -> None:
        self.policy.reset(candidates)
        self.rule.reset(candidates)

    def decide(self, obs: Observation) -> Decision:
        own = self.policy.decide(obs)
        jerk = float(self.rule.decide(obs).action[1])
        return Decision(np.array([own.action[0], jerk]), own.path_index, own.speed_mode,
                        shield_braking=jerk < float(own.action[1]) - 1e-6)


def collect(expert: IdcController | RuleBrakingExpert, student: IdcController, scene_list: list[tuple[Path, int]],
            expert_drives: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int]]:
    """(student inputs (n, width), labels before tanh (n, 2), whether the shield braked (n,),
    outcomes) of the scenes."""
    states, labels, braked, outcomes = [], [], [], {}
    for path, seed in scene_list:
        spec = load_scenario(path)
        config = dataclasses.replace(to_world_config(spec, path.parent), timeout_s=60.0)
        with World(config) as world:
            obs = world.reset(seed)
            expert.reset(world.candidates)
            student.reset(world.candidates)
            outcome = None
            while outcome is None:
                label = expert.decide(obs)
                mode = student.speed_mode(obs)
                row = build_states(obs.ego, select_others(obs.ego, obs.perceived.observations, obs.perceived.kinds),
                                   world.candidates, mode, student.preview)[label.path_index]
                states.append(row)
                labels.append(np.arctanh(np.clip(label.action / SCALE, -0.999, 0.999)).clip(-Z_LIMIT, Z_LIMIT))
                braked.append(bool(label.shield_braking))
                action = label.action if expert_drives else student.decide(obs).action
                obs, outcome = world.step(action)
            outcomes[outcome.kind] = outcomes.get(outcome.kind, 0) + 1
    return np.array(states), np.array(labels), np.array(braked), outcomes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", type=Path)
    parser.add_argument("-o", "--out", type=Path, required=True)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seeds", type=int, default=2, help="runs of each scenario per round")
    parser.add_argument("--fit-steps", type=int, default=1500)
    parser.add_argument("--lr", type=float, default=1e-4)
    parser.add_argument("--base-seed", type=int, default=7)
    parser.add_argument("--braking-weight", type=float, default=1.0,
                        help="how much more often a state the shield braked in is drawn for the fit")
    parser.add_argument("--squashed", action="store_true",
                        help="fit the actions after tanh (shares of their ranges), not the means before it")
    parser.add_argument("--expert", choices=("shield", "rule"), default="shield",
                        help="shield: the source with its shield; rule: its steering, the rule controller's jerk")
    args = parser.parse_args()
    torch.set_num_threads(1)
    started = time.monotonic()
    nets, config = load_networks(args.source)
    expert: IdcController | RuleBrakingExpert = (IdcController(nets.policy, nets.value, shield=True)
                                                  if args.expert == "shield"
                                                  else RuleBrakingExpert(IdcController(nets.policy, nets.value)))
    student_policy = copy.deepcopy(nets.policy)
    student = IdcController(student_policy, nets.value)
    all_states, all_z, all_braked, notes = [], [], [], []
    for r in range(args.rounds):
        t0 = time.monotonic()
        states, z, braked, outcomes = collect(expert, student, scenes(args.seeds, args.base_seed + r), expert_drives=(r == 0))
        all_states.append(states)
        all_z.append(z)
        all_braked.append(braked)
        with torch.no_grad():
            mean = student_policy.distribution(torch.as_tensor(states, dtype=torch.float32))[0].numpy()
            before = float(((mean - z) ** 2).mean())
            before_action = float(((np.tanh(mean) - np.tanh(z)) ** 2).mean())
        weights = (None if args.braking_weight == 1.0  # uniform draws
                   else torch.as_tensor(np.where(np.concatenate(all_braked), args.braking_weight, 1.0)))
        loss = fit_mean(student_policy, torch.as_tensor(np.concatenate(all_states), dtype=torch.float32),
                        torch.as_tensor(np.concatenate(all_z), dtype=torch.float32), args.fit_steps, args.lr, 256,
                        torch.Generator().manual_seed(r), weights, args.squashed)
        line = (f"round {r}: {'expert' if r == 0 else 'student'} drove {sum(outcomes.values())} episodes {outcomes}; "
                f"{len(states)} states ({int(braked.sum())} braked), label MSE before the fit {before:.3f} (after tanh {before_action:.4f}), fit loss {loss:.3f} ({time.monotonic() - t0:.0f} s)")
        print(line, flush=True)
        notes.append(line)
        write_refitted_model(args.out, config, (student_policy, nets.value, nets.adversary), args.source,
                             [f"DAgger with {args.source}{'+shield' if args.expert == 'shield' else ' and the rule controller jerk'} as the expert"] + notes, time.monotonic() - started)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
