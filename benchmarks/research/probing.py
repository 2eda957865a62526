"""What the benchmarks that probe a trained model inside seeded episodes share.

``failure_modes.py``, ``adversary_strength.py`` and ``value_ordering.py`` all take a scenario and a
model, drive the scenario's seeded episodes (the seeds of ``crossroads evaluate``) with the model's
online decision, and look at some of the states on the way.
"""

from __future__ import annotations

import argparse
import math
from collections import deque
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from crossroads.constants import JERK_MAX, PENALTY_RHO, SIM_STEP_S, STEER_RATE_MAX
from crossroads.idc.controller import Decision
from crossroads.idc.decision import IdcController
from crossroads.idc.observed import observed_others
from crossroads.idc.state import KIND_ROWS, N_OTHERS, build_states, path_tensors
from crossroads.planning import CandidatePath
from crossroads.rl.buffer import Samples
from crossroads.rl.idc_model import IDCModel, Rollout, StateBatch
from crossroads.rl.sampler import observation_sample
from crossroads.sim.snapshot import Snapshot
from crossroads.sim.observation import GroundTruth, Observation
from crossroads.sim.outcome import Outcome
from crossroads.sim.world import World

HORIZON = 25  # the paper's T, the training model's rollout length
STANDING_MPS = 0.5  # a participant slower than this stands
CORRIDOR_HALF_WIDTH_M = 2.5  # [m] |across| of a vehicle "ahead" of the ego
IN_THE_WAY_M = 10.0  # [m] how far ahead of the ego's centre a participant still holds it up
# a vehicle ahead standing this long holds the ego in one of the world's gridlocks, which no driver
# can pass (docs/tried/world.md: of the rule controller's timeouts, 29 of 32 had stood ≥ 41 s even
# with a 150 s timeout)
GRIDLOCK_STOOD_S = 30.0
ACTION_SCALE = torch.tensor([STEER_RATE_MAX, JERK_MAX])  # tanh(raw plan) × this = u = [Δδ, Δa]


def ego_frame(ego: np.ndarray, x: Any, y: Any) -> tuple[Any, Any]:
    """(along, across) [m] of the points (x, y) in the frame of ``ego`` (its position and heading φ)."""
    c, s = math.cos(float(ego[4])), math.sin(float(ego[4]))
    dx, dy = x - ego[0], y - ego[1]
    return c * dx + s * dy, -s * dx + c * dy


def vehicle_ahead(ego: np.ndarray, others: np.ndarray) -> int | None:
    """The slot of ``others`` (16, 6) holding the closest vehicle ahead of ``ego`` within
    ``CORRIDOR_HALF_WIDTH_M`` of its axis, or None."""
    vehicles = np.arange(N_OTHERS)[KIND_ROWS["vehicle"]]
    along, across = ego_frame(ego, others[vehicles, 0], others[vehicles, 1])
    ahead = np.flatnonzero((along > 0.0) & (np.abs(across) < CORRIDOR_HALF_WIDTH_M))
    return int(vehicles[ahead[np.argmin(along[ahead])]]) if len(ahead) else None


def in_the_way(ego: np.ndarray, snap: Snapshot) -> int | None:
    """The row of ``snap`` closest ahead of ``ego`` (any kind) within ``IN_THE_WAY_M`` of its centre and
    ``CORRIDOR_HALF_WIDTH_M`` of its axis, or None."""
    along, across = ego_frame(ego, np.asarray(snap.x), np.asarray(snap.y))
    near = np.flatnonzero((along > 0.0) & (along < IN_THE_WAY_M) & (np.abs(across) < CORRIDOR_HALF_WIDTH_M))
    return int(near[np.argmin(along[near])]) if len(near) else None


def timeout_cause(final: Observation, truth: GroundTruth) -> str:
    """What held the ego when its episode timed out, from the last observation and the world's true
    state then: the world's gridlock
    (a vehicle ahead standing ≥ ``GRIDLOCK_STOOD_S``), a shorter queue, or else where the ego was
    (before the stop line or inside the junction), whether it stood, and what was in its way."""
    stood = final.front_vehicle_stopped_s
    if stood >= GRIDLOCK_STOOD_S:
        return f"behind a vehicle standing ≥ {GRIDLOCK_STOOD_S:g} s"
    if stood > 0.0:
        return f"behind a vehicle standing < {GRIDLOCK_STOOD_S:g} s"
    place = "inside the junction" if final.past_stop_line else "before the stop line"
    motion = "standing" if final.ego[2] < STANDING_MPS else "moving"
    snap = truth.participants
    row = in_the_way(final.ego, snap)
    if row is None:
        way = f"nothing within {IN_THE_WAY_M:g} m ahead"
    else:
        way = f"a {'standing' if snap.speed[row] < STANDING_MPS else 'moving'} {snap.kind[row]} ahead"
    return f"{place}, ego {motion}, {way}"


def model_parser(description: str, runs: int) -> argparse.ArgumentParser:
    """A parser with the arguments every probing benchmark takes: scenario, --policy, --runs."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("scenario", type=Path)
    parser.add_argument("--policy", required=True, help="a trained model (.pt)")
    parser.add_argument("--runs", type=int, default=runs, help="seeded episodes of the scenario")
    return parser


def probed_states(world: World, controller: IdcController, seeds: Sequence[int],
                  every: int) -> Iterator[tuple[Observation, Decision]]:
    """Drive each seeded episode to its end; yield (observation, decision) every ``every`` steps."""
    for seed in seeds:
        obs = world.reset(seed)
        controller.reset(world.candidates)
        outcome, step = None, 0
        while outcome is None:
            decision = controller.decide(obs)
            if step % every == 0:
                yield obs, decision
            obs, outcome = world.step(decision.action)
            step += 1


@dataclass(frozen=True)
class Ending:
    """How a seeded episode ended, and the state a look-back before its end."""

    outcome: Outcome
    final: Observation  # the observation the world returned with the outcome
    truth: GroundTruth  # the world's true state then
    before: Samples  # the state (one row) on the chosen path, ``look_back_s`` before the end
    mode: str  # the speed mode then
    stood_s: float  # how long the vehicle ahead had stood then [s]
    ego_stood_s: float  # how long the ego itself had stood (< STANDING_MPS) at the end [s]


def episode_endings(world: World, controller: IdcController, seeds: Sequence[int],
                    look_back_s: float) -> Iterator[Ending]:
    """Drive each seeded episode to its end with ``controller``; yield how each ended (at most 5 s
    of look-back: 50 steps)."""
    steps = max(1, min(50, round(look_back_s / 0.1)))
    for seed in seeds:
        obs = world.reset(seed)
        controller.reset(world.candidates)
        recent: deque[tuple[Samples, str, float]] = deque(maxlen=steps + 1)
        outcome, ego_stood_steps = None, 0
        while outcome is None:
            decision = controller.decide(obs)
            recent.append((observation_sample(obs, int(decision.path_index), decision.speed_mode == "stop"),
                           decision.speed_mode, obs.front_vehicle_stopped_s))
            obs, outcome = world.step(decision.action)
            ego_stood_steps = ego_stood_steps + 1 if obs.ego[2] < STANDING_MPS else 0
        before, mode, stood = recent[0]
        yield Ending(outcome, obs, world.truth, before, mode, stood, ego_stood_steps * SIM_STEP_S)


def collision_lookbacks(world: World, controller: IdcController, seeds: Sequence[int],
                        look_back_s: float) -> Iterator[Ending]:
    """The endings of the seeded episodes that end in a collision."""
    return (e for e in episode_endings(world, controller, seeds, look_back_s) if e.outcome.kind == "collision")


def optimise_plans(model: IDCModel, batch: StateBatch, raw: torch.Tensor, steps: int, lr: float = 0.05
                   ) -> tuple[torch.Tensor, Rollout]:
    """Adam on the T actions of every state alone (no policy), minimising J_π = J_track + ρ J_safe
    with ξ ≡ 0, from the plans ``raw`` (B, T, 2) before tanh: the actions go through tanh into
    their ranges, so every step stays feasible. (the optimised raw plans, their rollout)."""
    scale = ACTION_SCALE.to(batch.ego.dtype)
    raw = raw.detach().clone().requires_grad_(True)
    optimiser = torch.optim.Adam([raw], lr=lr)

    def plan(_s: torch.Tensor, i: int) -> torch.Tensor:
        return torch.tanh(raw[:, i]) * scale

    for _ in range(steps):
        out = model.rollout(batch, plan, None, HORIZON)
        optimiser.zero_grad()
        (out.j_track + PENALTY_RHO * out.j_safe).sum().backward()  # states are independent: a sum
        optimiser.step()
    with torch.no_grad():
        return raw.detach(), model.rollout(batch, plan, None, HORIZON)


def policy_plan(model: IDCModel, policy: torch.nn.Module, batch: StateBatch, horizon: int = HORIZON
                ) -> tuple[torch.Tensor, Rollout]:
    """The policy's own plan from each state of ``batch``: its ``horizon`` actions before tanh
    (B, T, 2), as :func:`optimise_plans` starts from them, and its rollout (ξ ≡ 0)."""
    actions: list[torch.Tensor] = []

    def act(s: torch.Tensor, _: int) -> torch.Tensor:
        actions.append(policy.mean_action(s))
        return actions[-1]

    with torch.no_grad():
        out = model.rollout(batch, act, None, horizon)
    return torch.atanh((torch.stack(actions, 1) / ACTION_SCALE.to(out.s0.dtype)).clamp(-0.999, 0.999)), out


def open_loop_optimum(model: IDCModel, batch: StateBatch, steps: int = 250, lr: float = 0.05) -> Rollout:
    """The model's own best plan from each state (``optimise_plans`` from zero actions): its rollout."""
    zero = torch.zeros(batch.ego.shape[0], HORIZON, 2, dtype=batch.ego.dtype)
    return optimise_plans(model, batch, zero, steps, lr)[1]


class ModelOptimumController(IdcController):
    """Receding-horizon control on the training model: the value network picks τ* and the light logic
    the mode as in IDC, but the command is the first action of the model's own optimal plan for that
    path (``optimise_plans``), not the policy's. The first plan of an episode starts from the
    policy's (``first_steps`` Adam steps); every later one from the last, shifted one step (``steps``),
    also when τ* changes: the plans of neighbouring paths differ little, and τ* changes often.

    What a perfectly trained policy would do, where the model's predictions hold: it shows whether a
    target is out of reach of the cost J_π itself or only of the policy. Slow: 0.5–1.4 s a decision
    with 15–40 steps on a 2-core CPU."""

    def __init__(self, policy: torch.nn.Module, value: torch.nn.Module, steps: int = 40,
                 first_steps: int = 150, braking_floor: bool = False) -> None:
        super().__init__(policy, value, name="model optimum")
        self.steps = steps
        self.first_steps = first_steps
        self.braking_floor = braking_floor
        self._model: IDCModel | None = None
        self._plan: torch.Tensor | None = None

    def reset(self, candidates: Sequence[CandidatePath]) -> None:
        super().reset(candidates)
        self._model = IDCModel(path_tensors(candidates), braking_floor=self.braking_floor, preview=self.preview)
        self._plan = None

    def decide(self, observation: Observation) -> Decision:
        assert self._model is not None, "reset() first"
        mode = self.speed_mode(observation)
        others, kappa = observed_others(observation)
        states = build_states(observation.ego, others, self._candidates, mode, self.preview)
        best, _, values = self.decide_states(states)
        f = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float32)[None]  # noqa: E731
        batch = StateBatch(f(observation.ego), f(others), f(kappa), torch.tensor([best]),
                           torch.tensor([mode == "stop"]))
        if self._plan is None:
            start, _ = policy_plan(self._model, self.policy, batch)
            steps = self.first_steps
        else:
            start = torch.cat([self._plan[:, 1:], self._plan[:, -1:]], dim=1)
            steps = self.steps
        self._plan, _ = optimise_plans(self._model, batch, start, steps)
        action = (torch.tanh(self._plan[0, 0]) * ACTION_SCALE).double().numpy()
        return Decision(action, best, mode, values)
