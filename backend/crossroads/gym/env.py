"""``Crossroads-v0``: one scenario's world as a Gymnasium environment.

    import gymnasium as gym
    import crossroads.gym  # registers Crossroads-v0 (or: gym.make("crossroads.gym:Crossroads-v0", ...))

    env = gym.make("Crossroads-v0", scenario="scenarios/nominal/c_three_lane-left.yaml")
    env = gym.make("Crossroads-v0", scenario="c_three_lane", task="left")   # catalogue name + task
    obs, info = env.reset(seed=1705482282)   # the episode of `crossroads run ... --seed 1705482282`

* ``reset(seed=N)`` starts the world's episode N: the same traffic, lights, abnormal vehicles and
  perception noise as ``crossroads run SCENARIO --seed N`` (and as run N of a batch whose seed list
  holds N). ``reset()`` without a seed draws the next episode seed from the environment's generator,
  itself seeded by the last seed given or, before any, by the scenario's ``seed``: every episode
  follows from a seed.
* Observation, tracked path: :mod:`crossroads.gym.observation`; reward: :mod:`crossroads.gym.reward`;
  action: [Δδ rad/s, Δa m/s³] in ±0.4 and ±4.5 (the ego model clips, as for every controller).
* ``info``: ``outcome`` (None while the episode runs), ``travel_time_s`` (passed episodes: stop line
  to exit, SPEC §8), ``time_s``, ``seed``, ``path`` (the tracked candidate), ``speed_mode``, the
  reward's parts and, on the last step, ``detail`` (what was hit, ...).
* An episode SUMO cannot go on with ends with outcome ``error`` (terminated; its reward is the
  ``error`` entry of the outcome rewards): SUMO places the ego on the lanes of its route, and an ego
  more than 100 m from them (one driving straight on, far, in a left-turn scenario) cannot be placed.
* libsumo runs one simulation per process: run several environments in a vector env of processes
  (``gymnasium.vector.AsyncVectorEnv``); two in one process cannot both be reset.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from crossroads.gym.observation import (
    IdcView,
    ObservationKind,
    PathChoice,
    action_space,
    idc_view,
    observation_space,
    state_width,
)
from crossroads.gym.reward import RewardConfig, reward_parts, step_reward
from crossroads.scenario.spec import (
    ScenarioSpec,
    load_scenario,
    to_world_config,
    validate_scenario,
)
from crossroads.sim.observation import Observation
from crossroads.sim.sumo import SumoError
from crossroads.sim.world import World

SEED_LIMIT = 2**31 - 1  # episode seeds are SUMO seeds: 31 bits (scenario.spec.SEED_MASK)
TASKS = ("left", "straight", "right")


def scenario_spec(scenario: str | Path | ScenarioSpec, task: str | None = None) -> tuple[ScenarioSpec, Path | None]:
    """(the spec, the directory relative net paths count from) of a scenario file, a spec, or a
    catalogue intersection name with ``task`` (then every other field has its default)."""
    if isinstance(scenario, ScenarioSpec):
        if task is not None and task != scenario.task:
            raise ValueError(f"task {task!r} differs from the scenario's task {scenario.task!r}")
        return scenario, None
    text = str(scenario)
    if text.endswith((".yaml", ".yml")):
        spec = load_scenario(text)
        if task is not None and task != spec.task:
            raise ValueError(f"task {task!r} differs from the task {spec.task!r} of {text}")
        return spec, Path(text).parent
    if task not in TASKS:
        raise ValueError(f"scenario {text!r} is a catalogue intersection: give task= one of "
                         f"{', '.join(TASKS)} (got {task!r}), or a scenario file (.yaml)")
    spec = validate_scenario({"version": 1, "name": f"{text}-{task}", "intersection": text, "task": task},
                             source=f"intersection {text!r}")
    return spec, None


class CrossroadsEnv(gym.Env[Any, np.ndarray]):
    """A scenario's world as a Gymnasium environment (module docstring)."""

    metadata = {"render_modes": []}

    def __init__(
        self,
        scenario: str | Path | ScenarioSpec,
        task: str | None = None,
        *,
        observation: ObservationKind = "box",
        path: PathChoice = "nearest",
        preview: bool = False,
        reward: RewardConfig | None = None,
        render_mode: str | None = None,
    ) -> None:
        if observation not in ("box", "dict"):
            raise ValueError(f"observation must be 'box' or 'dict', got {observation!r}")
        if render_mode is not None:
            raise ValueError(f"render_mode {render_mode!r}: this environment does not render; "
                             "save a trace (crossroads run --trace) and play it in the 3D view")
        self.scenario, base_dir = scenario_spec(scenario, task)
        self.world = World(to_world_config(self.scenario, base_dir=base_dir))
        n = len(self.world.candidates)
        if path != "nearest" and not (isinstance(path, int) and not isinstance(path, bool) and 0 <= path < n):
            raise ValueError(f"path must be 'nearest' or a candidate index 0..{n - 1}, got {path!r}")
        self.observation_kind: ObservationKind = observation
        self._every = observation == "dict"  # every candidate's state (the box needs the tracked one's)
        self.path_choice: PathChoice = path
        self.preview = preview
        self.reward_config = reward or RewardConfig()
        self.action_space = action_space()
        self.observation_space = observation_space(observation, state_width(preview), n)
        self.render_mode = render_mode
        # every episode seed follows from a seed: before reset(seed=...), the scenario's
        self._np_random, self._np_random_seed = gym.utils.seeding.np_random(self.scenario.seed)
        self.observation: Observation | None = None  # the world's last observation (all of it)
        self._view: IdcView | None = None
        self.episode_seed: int | None = None
        self._done = True

    @property
    def candidates(self) -> tuple[Any, ...]:
        """The candidate paths, in the order of the dict observation's rows."""
        return self.world.candidates

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        if seed is not None and not (0 <= int(seed) <= SEED_LIMIT):
            raise ValueError(f"seed must be in 0..{SEED_LIMIT} (a SUMO seed), got {seed}")
        super().reset(seed=seed)
        self.episode_seed = int(seed) if seed is not None else int(self.np_random.integers(0, SEED_LIMIT))
        self.observation = self.world.reset(self.episode_seed)
        self._view = idc_view(self.observation, self.preview, self.path_choice, self._every)
        self._done = False
        info = {"seed": self.episode_seed, "scenario": self.scenario.name, "candidates": len(self.candidates),
                "path": self._view.path, "speed_mode": self._view.speed_mode, "time_s": 0.0}
        return self._view.observation(self.observation_kind), info

    def step(self, action: np.ndarray) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        if self._done or self._view is None:
            raise RuntimeError("the episode has ended (or not started): call reset() first")
        action = np.asarray(action, dtype=np.float64).reshape(-1)
        values = action.tolist()
        if len(values) != 2 or not (math.isfinite(values[0]) and math.isfinite(values[1])):
            raise ValueError(f"action must be 2 finite numbers [Δδ rad/s, Δa m/s³], got {action!r}")
        before = self._view
        try:
            self.observation, outcome = self.world.step(action)
        except SumoError as exc:  # SUMO lost the ego: the episode cannot go on (module docstring)
            self._done = True
            parts = step_reward(self.reward_config, before.state, action, before.state, "error")
            return (before.observation(self.observation_kind), parts.total, True, False,
                    {"outcome": "error", "travel_time_s": None, "time_s": round(self.observation.time_s, 3),
                     "seed": self.episode_seed, "path": before.path, "speed_mode": before.speed_mode,
                     "utility": parts.utility, "penalty": parts.penalty, "outcome_reward": parts.outcome,
                     "detail": str(exc)})
        self._view = idc_view(self.observation, self.preview, self.path_choice, self._every)
        kind = None if outcome is None else outcome.kind
        parts = reward_parts(self.reward_config, before.state, values[0], values[1], self._view.state, kind)
        info: dict[str, Any] = {
            "outcome": kind, "travel_time_s": None, "time_s": round(self.observation.time_s, 3),
            "seed": self.episode_seed, "path": self._view.path, "speed_mode": self._view.speed_mode,
            "utility": parts.utility, "penalty": parts.penalty, "outcome_reward": parts.outcome,
        }
        terminated = truncated = False
        if outcome is not None:
            self._done = True
            crossed = self.world.stop_line_crossed_s
            if kind == "passed" and crossed is not None:
                info["travel_time_s"] = round(outcome.time_s - crossed, 3)
            info["detail"] = outcome.detail
            truncated = kind == "timeout"
            terminated = not truncated
        return self._view.observation(self.observation_kind), parts.total, terminated, truncated, info

    def close(self) -> None:
        self.world.close()
        super().close()
