"""State sampling from the SUMO world (Algorithm 1 "Sampling"), in parallel workers.

Rounds. The learner asks for sampling *rounds*; in round r every worker w drives one episode and
returns every state it passed through (:class:`~crossroads.rl.buffer.Samples`). Everything random in
that episode comes from ``numpy.random.default_rng([seed, w, r])``: the intersection and task (among
the config's), the candidate path τ (uniformly, Algorithm 1 "randomly select a path"), the light's
position in its cycle, the ego's start distance and speed, the world seed and the exploration noise.
A round carries the policy weights it must drive with, so a round's output depends only on
(seed, w, r, weights): sampling is reproducible however the processes are scheduled, and a resumed
run re-issues the round that was in flight with the weights saved for it.

Driving **(choice)**: rounds r < ``rule_rounds`` drive with the rule-based controller (an untrained
policy leaves the road within a few steps); later rounds with the policy's mean action on τ plus
Gaussian exploration noise (``explore_std`` of each half range), clipped, except a share
``rule_share`` of them, still driven by the rule controller. Each episode's traffic is SPEC §2's
scaled by a factor drawn from ``demand_scale``, and a share ``empty_share`` of the episodes has no
traffic at all. A share ``standing_car_share`` of the recorded states is returned twice, the copy
with a car standing on τ ahead of the ego (``rl.augment``). The speed mode is the
paper's light logic (``idc.lights.choose_speed_mode``): before the stop line pass on green and stop
on red as training demands (SPEC §2), the yellow rule on yellow, pass once past the line, stop
behind a stopped queue. The rule driver is given τ as its only candidate, so every recorded state lies
near the path it is recorded with: states recorded against another candidate than the one driven
(metres off to the side) made the road penalty dwarf everything else and saturated the policy.

Per step the worker records the ego (8), the 16 others (``idc.state.select_others`` of the perceived,
noisy observations) and each one's curvature 1/R (``World.curvatures`` of their true lanes, put in the
same slots by running ``select_others`` a second time with the speed column replaced by κ: the slot
order depends on positions only), the global path index and the mode.

Executors: :class:`InlineSampler` (``workers = 0``, in the learner's process), :class:`ProcessSampler`
(multiprocessing *spawn*, one libsumo simulation per process), :class:`RaySampler` (``ray_address``:
Ray actors; ``ray`` is imported only then). All share submit(r, weights) / collect() (oldest round
first, outputs concatenated in worker order).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import traceback
from collections import deque
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from crossroads.constants import JERK_MAX, STEER_RATE_MAX
from crossroads.idc.lights import choose_speed_mode
from crossroads.idc.observed import observed_others
from crossroads.idc.state import build_states
from crossroads.planning import CandidatePath
from crossroads.rl.augment import standing_car_copies
from crossroads.rl.buffer import Samples
from crossroads.rl.config import TrainConfig
from crossroads.sim.config import EgoStart, SignalStart, WorldConfig
from crossroads.sim.ego import clip_action
from crossroads.sim.observation import Observation
from crossroads.sim.traffic import TrafficDemand
from crossroads.sim.world import World

PolicyWeights = dict[str, np.ndarray]  # a policy's state_dict as numpy arrays (picklable everywhere)


# --- the candidate paths of a run ------------------------------------------------------------------


def net_file(intersection: str) -> str:
    """The .net.xml of a catalogued intersection (built once, then cached)."""
    from crossroads.intersections import catalogue

    return str(catalogue.build(intersection))


@dataclass(frozen=True)
class PathSet:
    """Every candidate path of every (intersection, task) of a run, with a global index each.

    ``keys[k] = (intersection, task, j)``: candidate j of that world. The padded torch tensor of all
    of them (``idc.state.path_tensors(candidates)``) is what the model indexes with ``StateBatch.path``.
    """

    keys: tuple[tuple[str, str, int], ...]
    candidates: tuple[CandidatePath, ...]

    @staticmethod
    def build(intersections: tuple[str, ...], tasks: tuple[str, ...]) -> PathSet:
        keys, cands = [], []
        for name in intersections:
            net = net_file(name)
            for task in tasks:
                world = World(WorldConfig(net_file=net, task=task))  # type: ignore[arg-type]
                try:
                    for j, c in enumerate(world.candidates):
                        keys.append((name, task, j))
                        cands.append(c)
                finally:
                    world.close()
        return PathSet(tuple(keys), tuple(cands))

    def index(self) -> dict[tuple[str, str, int], int]:
        return {k: i for i, k in enumerate(self.keys)}

    def tensors(self, dtype: Any = None, device: Any = None) -> Any:
        from crossroads.idc.state import path_tensors

        return path_tensors(self.candidates, dtype=dtype, device=device)


# --- one observation → one sample ------------------------------------------------------------------


def as_sample(ego: np.ndarray, others: np.ndarray, kappa: np.ndarray, path_key: int, stop: bool) -> Samples:
    """One state as a one-row :class:`Samples` (what the buffer stores): the ego, the 16 others and
    their curvatures (``idc.observed.observed_others``), the path's index in the caller's path tensor, the mode."""
    return Samples(ego[None].astype(np.float32), others[None].astype(np.float32), kappa[None].astype(np.float32),
                   np.array([path_key], np.int64), np.array([stop]))


def observation_sample(obs: Observation, path_key: int, stop: bool) -> Samples:
    """:func:`as_sample` of an observation."""
    return as_sample(obs.ego, *observed_others(obs), path_key, stop)


def scaled_demand(factor: float) -> TrafficDemand:
    """SPEC §2 traffic with every density multiplied by ``factor``."""
    nominal = TrafficDemand()
    return TrafficDemand(vehicles_per_hour=factor * nominal.vehicles_per_hour,
                         cyclists_per_hour=factor * nominal.cyclists_per_hour,
                         pedestrians_per_hour=factor * nominal.pedestrians_per_hour)


def speed_mode(obs: Observation) -> str:
    return choose_speed_mode(
        front_vehicle_stopped_s=obs.front_vehicle_stopped_s, past_stop_line=obs.past_stop_line,
        light=obs.light.light, distance_to_stop_line_m=obs.distance_to_stop_line_m,
        speed_mps=float(obs.ego[2]), yellow_remaining_s=obs.light.remaining_s)


# --- a worker ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class WorkerSpec:
    """What a worker needs to know (picklable)."""

    config: TrainConfig
    keys: tuple[tuple[str, str, int], ...]


class EpisodeSampler:
    """Drives sampling episodes in this process (one World at a time: libsumo is per process)."""

    def __init__(self, spec: WorkerSpec, worker_id: int) -> None:
        import torch

        from crossroads.rl.neural_nets import DrivingPolicy

        self.config = spec.config
        self.worker_id = worker_id
        self.index = {k: i for i, k in enumerate(spec.keys)}
        self.combos = [(n, t) for n in self.config.intersections for t in self.config.tasks]
        self.n_candidates = {(n, t): sum(1 for k in spec.keys if k[:2] == (n, t)) for n, t in self.combos}
        self._phases: dict[tuple[str, str], tuple[float, ...]] = {}
        self._nets: dict[str, str] = {}
        with torch.random.fork_rng(devices=[]):  # leave the learner's global torch RNG untouched
            self.policy = DrivingPolicy(self.config.hidden_layers, self.config.hidden_units,
                                        self.config.path_preview, self.config.lead_input,
                                        self.config.participant_encoder)
        self.policy.eval()
        self._torch = torch

    def _net(self, name: str) -> str:
        if name not in self._nets:
            self._nets[name] = net_file(name)
        return self._nets[name]

    def _phase_durations(self, name: str, task: str) -> tuple[float, ...]:
        if (name, task) not in self._phases:
            probe = World(WorldConfig(net_file=self._net(name), task=task))  # type: ignore[arg-type]
            self._phases[(name, task)] = tuple(p.duration_s for p in probe.program.phases)
            probe.close()
        return self._phases[(name, task)]

    def load_weights(self, weights: PolicyWeights | None) -> None:
        if weights is not None:
            self.policy.load_state_dict({k: self._torch.as_tensor(v) for k, v in weights.items()})

    def episode_config(self, rng: np.random.Generator) -> tuple[WorldConfig, str, str, int]:
        """A random world for one episode: (config, intersection, task, candidate j)."""
        cfg = self.config
        name, task = self.combos[int(rng.integers(len(self.combos)))]
        j = int(rng.integers(self.n_candidates[(name, task)]))
        durations = np.asarray(self._phase_durations(name, task))
        t = rng.uniform(0.0, durations.sum())  # a uniform instant of the light's cycle
        phase = int(np.searchsorted(np.cumsum(durations), t, side="right"))
        phase = min(phase, len(durations) - 1)
        elapsed = float(t - (np.cumsum(durations)[phase] - durations[phase]))
        ego_start = EgoStart(distance_to_stop_line_m=float(rng.uniform(*cfg.start_distance_m)),
                             speed_mps=float(rng.uniform(*cfg.start_speed_mps)))
        demand_factor = float(rng.uniform(*cfg.demand_scale))
        if cfg.empty_share > 0.0 and rng.random() < cfg.empty_share:  # drawn only then: older runs' draws stay
            demand_factor = 0.0
        world_cfg = WorldConfig(
            net_file=self._net(name), task=task,  # type: ignore[arg-type]
            signal_start=SignalStart(phase_index=phase, elapsed_s=min(elapsed, durations[phase] - 0.1)),
            ego_start=ego_start, warmup_s=cfg.warmup_s, timeout_s=cfg.max_episode_steps * 0.1 + 1.0,
            demand=scaled_demand(demand_factor))
        return world_cfg, name, task, j

    def round(self, round_index: int, weights: PolicyWeights | None) -> Samples:
        """One episode of round ``round_index`` (module docstring)."""
        torch = self._torch
        cfg = self.config
        rng = np.random.default_rng([cfg.seed, self.worker_id, round_index])
        world_cfg, name, task, j = self.episode_config(rng)
        coin = rng.random()  # drawn in every round, so the stream of draws never depends on the round
        use_rule = round_index < cfg.rule_rounds or weights is None or coin < cfg.rule_share
        self.load_weights(weights)
        world = World(world_cfg)
        # the drawn candidate's entrance lane is the ego's start lane when it is one of the approach's
        cand_lane = world.candidates[j].entrance_lane
        if cand_lane != world.start_lane.id:
            world.close()
            world = World(replace(world_cfg, ego_start=replace(world_cfg.ego_start, entrance_lane=cand_lane)))
        path = world.candidates[j]
        key = self.index[(name, task, j)]
        rows: list[Samples] = []
        try:
            obs = world.reset(int(rng.integers(2**31 - 1)))
            rule = None
            if use_rule:
                from crossroads.idc.rule_based import RuleBasedController

                rule = RuleBasedController()
                rule.reset([path])
            noise_scale = cfg.explore_std * np.array([STEER_RATE_MAX, JERK_MAX])
            for _ in range(cfg.max_episode_steps):
                others, kappa = observed_others(obs)
                mode = speed_mode(obs)
                rows.append(as_sample(obs.ego, others, kappa, key, mode == "stop"))
                if rule is not None:
                    action = rule.decide(obs).action
                else:
                    state = build_states(obs.ego, others, [path], mode, self.config.path_preview)
                    with torch.no_grad():
                        mean = self.policy.mean_action(torch.as_tensor(state, dtype=torch.float32))[0]
                    action = clip_action(mean.numpy().astype(np.float64) + noise_scale * rng.standard_normal(2))
                obs, outcome = world.step(action)
                if outcome is not None:
                    break
        finally:
            world.close()
        recorded = Samples.concat(rows)
        # drawn after the episode, so the episode's own draws stay those of runs without the option
        extra = standing_car_copies(recorded, path, cfg.standing_car_share, cfg.standing_car_gap_m, rng,
                                    stoppable=cfg.standing_car_stoppable)
        return Samples.concat([recorded, extra])


# --- executors -------------------------------------------------------------------------------------


class Sampler(Protocol):
    workers: int

    def submit(self, round_index: int, weights: PolicyWeights | None) -> None: ...

    def collect(self) -> Samples: ...

    def close(self) -> None: ...


class InlineSampler:
    """Rounds run in the learner's process when collected (``workers = 0``: one episode per round)."""

    def __init__(self, spec: WorkerSpec) -> None:
        self.workers = 1
        self._sampler = EpisodeSampler(spec, 0)
        self._queue: deque[tuple[int, PolicyWeights | None]] = deque()

    def submit(self, round_index: int, weights: PolicyWeights | None) -> None:
        self._queue.append((round_index, weights))

    def collect(self) -> Samples:
        r, weights = self._queue.popleft()
        return self._sampler.round(r, weights)

    def close(self) -> None:
        self._queue.clear()


PARENT_CHECK_S = 2.0  # [s] how often an idle worker checks that its learner still lives


def _worker_main(spec: WorkerSpec, worker_id: int, inbox: Any, outbox: Any, parent: int) -> None:
    """A sampling process: answer each (round, weights) with (round, Samples) or ("error", text).
    ``parent``: the learner's pid (passed, not read here: the learner may die before this starts)."""
    import torch

    torch.set_num_threads(1)
    sampler = EpisodeSampler(spec, worker_id)
    while True:
        try:
            msg = inbox.get(timeout=PARENT_CHECK_S)
        except queue.Empty:
            # a learner killed by a signal never sends the None below: without this check its
            # workers would wait (and hold their memory) until the machine restarts
            if os.getppid() != parent:
                return
            continue
        if msg is None:
            return
        r, weights = msg
        try:
            outbox.put((r, sampler.round(r, weights)))
        except Exception:  # noqa: BLE001 — reported to the learner, which raises it
            outbox.put(("error", traceback.format_exc()))


class ProcessSampler:
    """``workers`` spawned processes, each with its own libsumo simulation."""

    def __init__(self, spec: WorkerSpec, workers: int) -> None:
        ctx = mp.get_context("spawn")
        self.workers = workers
        self._inboxes = [ctx.Queue() for _ in range(workers)]
        self._outboxes = [ctx.Queue() for _ in range(workers)]
        learner = os.getpid()
        self._procs = [ctx.Process(target=_worker_main, args=(spec, w, self._inboxes[w], self._outboxes[w], learner),
                                   daemon=True, name=f"crossroads-sampler-{w}") for w in range(workers)]
        for p in self._procs:
            p.start()
        self._pending: deque[int] = deque()

    def submit(self, round_index: int, weights: PolicyWeights | None) -> None:
        for box in self._inboxes:
            box.put((round_index, weights))
        self._pending.append(round_index)

    def collect(self) -> Samples:
        r = self._pending.popleft()
        parts = []
        for w, box in enumerate(self._outboxes):
            while True:
                try:
                    got, samples = box.get(timeout=5.0)
                    break
                except Exception:  # queue.Empty: check the worker is alive
                    if not self._procs[w].is_alive():
                        raise RuntimeError(f"sampling worker {w} died (exit code {self._procs[w].exitcode})") from None
            if got == "error":
                raise RuntimeError(f"sampling worker {w} failed:\n{samples}")
            assert got == r, (got, r)
            parts.append(samples)
        return Samples.concat(parts)

    def close(self) -> None:
        for box in self._inboxes:
            try:
                box.put(None)
            except (ValueError, OSError):
                pass
        for p in self._procs:
            p.join(timeout=10.0)
            if p.is_alive():
                p.terminate()
                p.join()
        self._pending.clear()


class RaySampler:
    """``workers`` Ray actors on the cluster at ``address`` (each actor: one process, one libsumo).

    The cluster's nodes need this package and the intersection catalogue installed.
    """

    def __init__(self, spec: WorkerSpec, workers: int, address: str) -> None:
        try:
            import ray
        except ImportError as exc:
            raise RuntimeError("ray_address was given but ray is not installed: pip install 'ray[default]'"
                               ) from exc
        self._ray = ray
        if not ray.is_initialized():
            ray.init(address=address)
        actor = ray.remote(num_cpus=1)(_RayWorker)
        self.workers = max(workers, 1)
        self._actors = [actor.remote(spec, w) for w in range(self.workers)]
        self._pending: deque[list[Any]] = deque()

    def submit(self, round_index: int, weights: PolicyWeights | None) -> None:
        ref = self._ray.put(weights)
        self._pending.append([a.round.remote(round_index, ref) for a in self._actors])

    def collect(self) -> Samples:
        return Samples.concat(self._ray.get(self._pending.popleft()))

    def close(self) -> None:
        for a in self._actors:
            self._ray.kill(a)
        self._pending.clear()


class _RayWorker:
    def __init__(self, spec: WorkerSpec, worker_id: int) -> None:
        import torch

        torch.set_num_threads(1)
        self._sampler = EpisodeSampler(spec, worker_id)

    def round(self, round_index: int, weights: PolicyWeights | None) -> Samples:
        return self._sampler.round(round_index, weights)


def make_sampler(config: TrainConfig, keys: tuple[tuple[str, str, int], ...]) -> Sampler:
    spec = WorkerSpec(config, keys)
    if config.ray_address:
        return RaySampler(spec, config.workers, config.ray_address)
    if config.workers == 0:
        return InlineSampler(spec)
    return ProcessSampler(spec, config.workers)


def policy_weights(policy: Any) -> PolicyWeights:
    """A policy's state_dict as numpy arrays (for the workers)."""
    return {k: v.detach().cpu().numpy().copy() for k, v in policy.state_dict().items()}


