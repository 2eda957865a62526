"""The training configuration of APG / DPG (SPEC §6, paper Algorithm 1 and Sec. V-A).

One typed, frozen dataclass; every field carries its unit and where its default comes from.
``TrainConfig()`` itself is the paper's configuration: its defaults are the paper's numbers (from
:mod:`crossroads.constants`), and where the paper is silent a project decision marked "(choice)" in
the field's docstring. Recipes that depart from the paper (the short-run learning rates, the
shipped models' own recipes) are named experiments in :mod:`crossroads.rl.experiments`, applied on
top of it. :func:`apply_overrides` turns ``key=value`` strings (the command line) into a new config
and names any unknown key or bad value.

Options whose experiment lost are removed with their code (:data:`REMOVED_OPTIONS`; what they
measured stays on docs/tried/training.md). A saved config that still names one loads when it holds
the value under which the option did nothing, and is refused with a one-line error otherwise.
"""

from __future__ import annotations

import dataclasses
import json
import typing
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any, Literal

from crossroads.constants import (
    ADAM_BETAS,
    ADVERSARY_UPDATE_INTERVAL,
    BATCH_SIZE,
    HIDDEN_LAYERS,
    HIDDEN_UNITS,
    HORIZON_T,
    LOG_INTERVAL,
    PENALTY_RHO,
    POLICY_LR,
    TAR_RUNS,
    TAR_STEPS,
    TOTAL_ITERATIONS,
    VALUE_LR,
)
from crossroads.network.road import TASKS

Algo = Literal["apg", "dpg"]
PolicyLoss = Literal["mean", "sqrt", "log"]  # how the driving policy weighs the states of a batch (rl.learner)
TRIED_PAGE = "docs/tried/training.md"  # where every training experiment's result is written, kept or not

DEFAULT_INTERSECTIONS: tuple[str, ...] = (
    "a_single_lane", "b_two_lane", "c_three_lane",
    "d_irregular_skewed", "e_irregular_oblique", "f_irregular_wide",
)  # the paper's six (Fig. 2 (a)-(f)), as catalogued under scenarios/intersections


@dataclass(frozen=True)
class TrainConfig:
    """Everything one training run needs. Frozen: a run's config never changes once started."""

    # --- algorithm (SPEC §6) ---------------------------------------------------------------------
    algo: Algo = "apg"
    """"apg": driving policy vs. adversary (min_θ max_φ J_π); "dpg": the baseline, ξ ≡ 0, no adversary."""
    iterations: int = TOTAL_ITERATIONS
    """Total optimisation iterations k (paper: 200 000). Also the period of the cosine annealing."""
    batch_size: int = BATCH_SIZE
    """Initial states per iteration (paper: 256)."""
    horizon: int = HORIZON_T
    """Prediction horizon T [steps of 0.1 s] of the differentiable model (paper: 25)."""
    rho: float = PENALTY_RHO
    """Penalty factor ρ of J_π = J_track + ρ J_safe (paper: 15)."""
    adversary_interval: int = ADVERSARY_UPDATE_INTERVAL
    """m: the adversary is updated at iterations k with k % m == 0 (paper: 5)."""
    nominal_floor: bool = True
    """(choice) APG: each safety constraint of the model is the worse of the adversary's prediction
    and the ξ ≡ 0 one (rl.idc_model), so a half-trained adversary cannot make the scene look safer than
    plain prediction does (measured: a slowly learning adversary sped up a standing queue ahead of the
    ego, and its policy drove into such queues). False: the adversary's prediction alone."""
    braking_floor: bool = False
    """(choice) Each safety constraint of the model is also the worse of the prediction and one with
    every participant braking at ``constants.OTHER_DECEL_MPS2`` to a stand (rl.idc_model), so a plan must
    stay safe if the car ahead brakes. Measured (docs/tried/training.md, "The model's own optimum"): the
    model's own receding-horizon optimum without it passed no more nominal left turns than the
    policy: at 8.3 m/s it braked too late for a queue whose last car was slowing from 1 m/s and hit it
    at 1.1 m/s; with the floor it braked in time. Off by default until a run has trained with it."""
    stopping_tail: int = 0
    """(choice) Steps [0.1 s] of full braking appended to every rollout's last state, every
    participant braking to a stand alongside; J_safe gets the squared reach of the ego's rest point
    (plus the safety margin) past each participant at rest ahead in its way (rl.idc_model,
    ``stopping_intrusion``): a terminal constraint that the plan end where the ego can still stop clear. 0 (paper): none; 40 covers full
    braking from the pass profile's 8.33 m/s (the safety shield's horizon). Why: from 8.33 m/s full
    braking takes ~3.3 s, longer than T = 25 steps, and every trained policy without it ran into
    standing queues at the pass profile's speed (docs/tried/training.md, "The stopping tail"). It
    taught the stop in the queue test but did not raise the passes; it stays because
    ``models/pooled/apg.pt`` trains with it (the ``pooled`` experiment)."""
    sample_actions: bool = True
    """Training rollouts draw u ~ π_θ and ξ ~ π_φ by reparameterisation (the paper's u ~ π_θ(s));
    False uses the tanh-squashed means (deterministic rollouts)."""

    policy_loss: PolicyLoss = "mean"
    """(choice) What the driving policy's step minimises over the batch's states s: "mean" (paper):
    J_π = mean_s (J_track + ρ J_safe)(s); "log": mean_s log(1 + J(s)), whose gradient weighs each
    state's by 1 / (1 + J(s)), so a relative improvement counts the same in every state; "sqrt":
    mean_s 2 √(1 + J(s)), weights 1 / √(1 + J(s)), between the two. Each state's best plan is the same under both; what differs is which states a
    network of finite size fits first. Under "mean" the few states with J in the hundreds (a car
    close ahead) set the direction of every step: measured (200 steps from an APG trained under
    "mean"), the plan on an empty road at the reference speed kept braking at full jerk (J_track 40 →
    30; the model's optimum 7) under "mean" and stopped braking within 50 steps under "log" (J_track
    8.1). The adversary keeps the paper's mean (it maximises J_π); logs report J_π as the mean."""
    pre_squash_bound: float = 2.5
    """(choice) |z| of the driving policy's pre-tanh means beyond which an output counts as saturated
    in the logs (``charts/saturated_share``): tanh(2.5) = 0.987, and past it tanh's slope vanishes
    (1 − tanh²(3) = 0.01), so J_π barely moves such an output any more. Only measured, never trained on."""

    # --- networks (Sec. V-A) ---------------------------------------------------------------------
    path_preview: bool = False
    """(choice) The networks also read the candidate path 5, 10, 15 and 20 m ahead of the reference
    point (its lateral offset and heading in the ego's frame and its v_ref: 12 inputs after the
    paper's 108, ``idc.state``). The paper's x_track holds the nearest point only and the networks
    drop the ego's absolute pose (one network for six intersections), so without the preview a policy
    cannot steer into a turn before it has begun nor slow before the pass profile drops: measured
    (docs/tried/training.md, "Seeing the path ahead"), a policy without it began to steer only
    once inside the Bezier of c_three_lane left-2 and swung 1.42 m wide, where a sequence steering in
    early stays within 0.18 m; 4 000 iterations more with the preview (the shipped APG) stayed within
    0.38 m there and reached the exit on all 38 paths (before: 33). A warm start from networks
    without it keeps their outputs (the new inputs' weights start at zero). False (paper): the 108
    values only."""
    lead_input: bool = False
    """(choice) The networks also read a lead summary computed from the state (3 inputs after the
    state's, ``idc.state.lead_features``): the bumper gap to the nearest participant in a straight
    corridor ahead of the ego and how fast the ego closes on it. The 16 participant slots are sorted
    by distance, so the car ahead sits in a different slot from scene to scene among the oncoming
    traffic; measured, 2 s before a collision with a vehicle ahead a trained policy's plan met it in
    3 of 31 states with the other slots padded and in 17 of 31 as seen. A warm start keeps the
    source's outputs (the new inputs' weights start at zero). False (paper): nothing added. It did not
    raise the passes (docs/tried/training.md); it stays because ``models/pooled/apg.pt`` reads it."""
    participant_encoder: int = 0
    """(choice) > 0: the driving policy and the value network read the 16 participants through one
    small network shared by every slot (this many units, 2 GELU layers), max-pooled over the slots
    (``rl.neural_nets.ParticipantPooling``), instead of 96 slot-specific inputs; the adversary keeps them
    flat (its ξ are per slot). Measured (``benchmarks/research/clutter_probe.py``): 2 s before a
    collision with a vehicle ahead, the shipped APG's plan kept clear of that vehicle alone in the first slot in
    29 of 32 states and alone in the slot it had as seen in 4. Flat networks start such a run only
    through ``crossroads train distill``. 0 (paper): the flat 108 inputs."""
    hidden_layers: int = HIDDEN_LAYERS
    """Hidden layers of every MLP (paper: 5)."""
    hidden_units: int = HIDDEN_UNITS
    """Units per hidden layer (paper: 256). Tests use 32."""

    # --- optimisation (Table "Training hyperparameters") -------------------------------------------
    policy_lr: tuple[float, float] = POLICY_LR
    """Driving policy learning rate, cosine annealed start → end over `iterations` (paper: 1e-4 → 2e-6)."""
    value_lr: tuple[float, float] = VALUE_LR
    """Value network learning rate, cosine annealed start → end (paper: 3e-4 → 1e-6)."""
    adversary_lr: tuple[float, float] = POLICY_LR
    """(choice) Adversary learning rate, start → end: the paper gives none; it "employs similar
    architecture" to the driving policy, so it gets the policy's schedule (1e-4 → 2e-6). Its
    scheduler steps every iteration, whether or not the adversary is updated then."""
    adam_betas: tuple[float, float] = ADAM_BETAS
    """Adam (β1, β2) of all three optimisers (paper: 0.9, 0.999)."""
    max_grad_norm: float | None = None
    """(choice) Clip each network's gradient to this global L2 norm; None (paper): no clipping."""

    # --- sampling (Algorithm 1 "Sampling") ---------------------------------------------------------
    intersections: tuple[str, ...] = DEFAULT_INTERSECTIONS
    """Catalogue names (or .yaml paths) of the intersections the workers sample on (default: all six)."""
    tasks: tuple[str, ...] = TASKS
    """Ego tasks sampled: left, straight, right (default all three)."""
    workers: int = 4
    """Sampling workers (paper: 10). Processes (multiprocessing spawn, one libsumo per process), or Ray
    actors with `ray_address`. 0 = sample inline in the learner's process (tests, debugging)."""
    ray_address: str | None = None
    """Address of a Ray cluster ("auto", "ray://host:10001"); None: local processes."""
    buffer_size: int = 100_000
    """(choice) Ring buffer capacity [states]; the oldest states are overwritten."""
    samples_per_iteration: float = 128.0
    """(choice) Sampling rounds are collected so that, on average, this many new states enter the
    buffer per iteration (replay ratio = batch_size / this = 2 by default)."""
    learning_starts: int = 1_000
    """(choice) States in the buffer before the first update (the learner waits for them)."""
    rule_rounds: int = 20
    """(choice) The first rounds drive with the rule-based controller (idc.rule_based): an untrained
    policy leaves the road within a few steps and would only show states near the episode starts.
    Later rounds drive with the current policy's mean action plus exploration noise."""
    rule_share: float = 0.25
    """(choice) After the first `rule_rounds`, each round is still driven by the rule-based
    controller with this probability (drawn from the round's generator): the buffer keeps states
    near the paths while the policy is poor, not only the states of its own mistakes."""
    demand_scale: tuple[float, float] = (0.0, 1.5)
    """(choice) Each sampling episode's traffic (SPEC §2 densities) is scaled by a factor drawn
    uniformly in this range, so the policy also sees empty and busier scenes (an empty scene makes
    every slot of x_other a pad, which nominal traffic never shows). (1, 1): always SPEC §2."""
    empty_share: float = 0.1
    """(choice) Share of sampling episodes with no traffic at all (drawn after ``demand_scale``; 0
    draws nothing, as runs before it did). A factor drawn from ``demand_scale`` leaves a scene empty
    only below ~0.03, and an APG never shown one braked from 8.33 to 3.5 m/s on an empty
    straight road: the scene of the paper's tracking claim (``benchmarks/tracking.py``)."""
    standing_car_share: float = 0.25
    """(choice) Share of the sampled states that also enter the buffer as a copy with a car standing
    on the path ahead of the ego (rl.augment): the first trained models' collisions were mostly with a
    vehicle standing in front, which the world shows only briefly in the pass mode. 0: none (runs
    before the option)."""
    standing_car_gap_m: tuple[float, float] = (0.5, 30.0)
    """(choice) [m] bumper gap of that car ahead of the ego, drawn uniformly (beyond the braking
    distance when ``standing_car_stoppable``)."""
    standing_car_stoppable: bool = True
    """(choice) Place that car the drawn gap *beyond* the distance full braking needs from the
    state's speed and acceleration (``sim.ego.braking_distance_m``), so every copy can be stopped
    for and its gradient says "brake". False: the gap is bumper to bumper, where
    at 8 m/s every gap under 14 m is a collision no plan avoids and the plan that hurts least
    swerves — a run trained so tracked its straight paths worse (0.044 → 0.29 m) and still hit the queue test's
    car from 6 and 8 m/s."""
    danger_share: float = 0.5
    """(choice) Share of every batch drawn from the buffer's dangerous states (J_safe of the
    policy's plan above ``danger_threshold``); 0 = the paper's uniform draws (rl.buffer)."""
    danger_threshold: float = 1.0
    """(choice) J_safe above which a state counts as dangerous for ``danger_share``."""
    explore_std: float = 0.1
    """(choice) Exploration noise of the sampling policy: Gaussian, this fraction of each action's
    half range (Δδ: 0.04 rad/s, Δa: 0.45 m/s³), clipped to the action ranges."""
    max_episode_steps: int = 600
    """Steps [0.1 s] of one sampling episode at most (an episode also ends on its outcome)."""
    warmup_s: float = 30.0
    """(choice) [s] SUMO warm-up before the ego enters, in sampling and TAR episodes."""
    start_distance_m: tuple[float, float] = (5.0, 60.0)
    """(choice) [m] the ego's start before the stop line is drawn uniformly in this range."""
    start_speed_mps: tuple[float, float] = (0.0, 8.33)
    """(choice) [m/s] the ego's start speed is drawn uniformly in this range (≤ 0.8·V_limit)."""

    # --- evaluation and logging (Sec. V-A, Fig. 4-5) ---------------------------------------------------
    log_every: int = LOG_INTERVAL
    """Iterations between metric rows (paper: 1000); each row also evaluates TAR."""
    tar_runs: int = TAR_RUNS
    """Real runs in the SUMO world per TAR evaluation (paper: 10)."""
    tar_steps: int = TAR_STEPS
    """Steps [0.1 s] summed per TAR run (paper: 120)."""
    tar_seed: int = 1_000_000
    """Run r of every TAR evaluation uses world seed tar_seed + r (a fixed set, the same each time)."""
    checkpoint_every: int = 10_000
    """Iterations between checkpoints (one is also written at the end)."""

    # --- run -----------------------------------------------------------------------------------------
    seed: int = 0
    """The run's seed: python, numpy, torch, the buffer's draws and every sampling world derive from it."""
    device: str = "cpu"
    """torch device of the learner ("cpu", "cuda"); workers always act on the CPU."""
    torch_threads: int = 0
    """torch intra-op threads of the learner; 0 leaves torch's default."""
    out: Path = Path("runs")
    """Directory under which the run directory `<algo>-seed<seed>` is created."""
    run_name: str | None = None
    """Name of the run directory; None: `<algo>-seed<seed>`."""
    init_from: Path | None = None
    """Warm start: the networks of a model file or checkpoint (`crossroads train export`) replace the
    fresh ones; optimisers, schedules and the iteration count start anew (unlike --resume)."""
    progress: bool = True
    """Show a progress bar with ETA on stderr."""
    tensorboard: bool = True
    """Also write TensorBoard events when torch.utils.tensorboard can be imported."""
    experiments: tuple[str, ...] = ()
    """The named experiments (``crossroads train --experiment``, rl.experiments) applied to the
    paper's configuration, in order, before any --set: a record of how the run was configured (their
    values are already in the other fields). (): the paper's configuration and --set alone."""

    def __post_init__(self) -> None:
        if self.algo not in ("apg", "dpg"):
            raise ValueError(f"algo: {self.algo!r} is neither 'apg' nor 'dpg'")
        for name in ("iterations", "batch_size", "horizon", "adversary_interval", "hidden_layers",
                     "hidden_units", "buffer_size", "max_episode_steps", "log_every", "checkpoint_every"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}: must be ≥ 1, got {getattr(self, name)}")
        if self.workers < 0:
            raise ValueError(f"workers: must be ≥ 0, got {self.workers}")
        if self.stopping_tail < 0:
            raise ValueError(f"stopping_tail: must be ≥ 0 steps, got {self.stopping_tail}")
        if self.samples_per_iteration <= 0:
            raise ValueError("samples_per_iteration: must be > 0")
        if not 0.0 <= self.danger_share <= 1.0:
            raise ValueError(f"danger_share: must lie in [0, 1], got {self.danger_share}")
        if not self.danger_threshold >= 0.0:
            raise ValueError(f"danger_threshold: must be ≥ 0, got {self.danger_threshold}")
        if not 0.0 <= self.standing_car_share <= 1.0:
            raise ValueError(f"standing_car_share: must lie in [0, 1], got {self.standing_car_share}")
        if self.participant_encoder < 0:
            raise ValueError(f"participant_encoder: must be ≥ 0 units, got {self.participant_encoder}")
        low, high = self.standing_car_gap_m
        if not 0.0 <= low <= high:
            raise ValueError(f"standing_car_gap_m: need 0 <= low <= high, got {self.standing_car_gap_m}")
        if not 0.0 <= self.empty_share <= 1.0:
            raise ValueError(f"empty_share: must lie in [0, 1], got {self.empty_share}")
        if not 0.0 <= self.rule_share <= 1.0:
            raise ValueError(f"rule_share: must lie in [0, 1], got {self.rule_share}")
        low, high = self.demand_scale
        if not 0.0 <= low <= high:
            raise ValueError(f"demand_scale: need 0 <= low <= high, got {self.demand_scale}")
        if self.learning_starts < self.batch_size:
            object.__setattr__(self, "learning_starts", self.batch_size)
        bad = [t for t in self.tasks if t not in TASKS]
        if bad or not self.tasks:
            raise ValueError(f"tasks: {bad or '()'} not among {TASKS}")
        if not self.intersections:
            raise ValueError("intersections: at least one is needed")

    @property
    def directory(self) -> Path:
        """The run directory."""
        return Path(self.out) / (self.run_name or f"{self.algo}-seed{self.seed}")

    def to_json(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["out"] = str(self.out)
        out["init_from"] = None if self.init_from is None else str(self.init_from)
        return out

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TrainConfig:
        """A saved config (a run's config.json, a checkpoint's, a model card's ``config``).

        A field the saved config predates gets the value its run trained with, so a resumed old run
        keeps its model instead of switching under its own checkpoints. A removed option
        (:data:`REMOVED_OPTIONS`) is dropped at its neutral value and refused otherwise."""
        data = dict(data)
        if "xi_positions" not in data and "nominal_floor" not in data:
            # written before either field existed: those runs added ξ_x, ξ_y at every step, a form
            # since removed. (Later configs either name xi_positions or, written after its removal,
            # name nominal_floor alone.)
            data["xi_positions"] = "step"
        data.setdefault("nominal_floor", False)  # the run trained against the adversary alone
        data.setdefault("empty_share", 0.0)  # likewise: keeps their sampling draws
        data.setdefault("standing_car_share", 0.0)  # likewise
        data.setdefault("standing_car_stoppable", False)  # likewise (their bumper gaps)
        return apply_overrides(cls(), data)


@dataclass(frozen=True)
class RemovedOption:
    """A training option whose experiment lost and whose code is gone."""

    hint: Any
    """Its type, as the field had it (to read a command-line string)."""
    neutral: Any
    """The value under which it did nothing: a saved config may still name it so."""
    anchor: str
    """The section of docs/tried/training.md that holds what it measured."""

    def refusal(self, name: str, value: Any) -> str:
        return (f"{name}={value!r}: this experiment was removed from training (see {TRIED_PAGE}#{self.anchor}); "
                f"only its neutral value {self.neutral!r} still loads")


REMOVED_OPTIONS: dict[str, RemovedOption] = {
    "xi_positions": RemovedOption(str, "offset", "the-adversary-2026-12-01"),
    # ("step": ξ_x, ξ_y added at every step as f_other is printed; the adversary could carry any
    # participant 20 m onto the ego and APG learned to flee. "offset" is what remains.)
    "pre_squash_weight": RemovedOption(float, 0.0, "which-states-the-policys-step-serves-2026-12-03"),
    "standing_car_neighbours": RemovedOption(int, 0, "what-the-adversary-and-the-queues-hid-2026-12-02"),
}
"""Removed options: name → its type, neutral value and the docs/tried/training.md anchor of its result."""


def without_removed_options(overrides: dict[str, Any]) -> dict[str, Any]:
    """``overrides`` without the removed options that hold their neutral value; any other value of
    one raises ValueError naming the option and where its result is written."""
    out = {}
    for key, value in overrides.items():
        removed = REMOVED_OPTIONS.get(key.replace("-", "_"))
        if removed is None:
            out[key] = value
            continue
        try:
            neutral = _coerce(key, removed.hint, value) == removed.neutral
        except (TypeError, ValueError):
            neutral = False
        if not neutral:
            raise ValueError(removed.refusal(key.replace("-", "_"), value))
    return out


def _coerce(name: str, hint: Any, value: Any) -> Any:
    """``value`` (a string from the command line, or JSON data) as the type ``hint`` of field ``name``."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if isinstance(value, str) and hint is not str and origin is not Literal:
        text = value.strip()
        if text.lower() in ("none", "null") and type(None) in args:
            return None
        if origin is tuple:
            value = [v for v in text.replace(",", " ").split() if v]
        elif hint is bool:
            if text.lower() not in ("1", "0", "true", "false", "yes", "no"):
                raise ValueError(f"{name}: {value!r} is not a boolean")
            return text.lower() in ("1", "true", "yes")
    if origin is tuple:
        items = list(value)
        inner = args[0] if len(args) == 2 and args[1] is Ellipsis else None
        types = [inner] * len(items) if inner else list(args)
        if len(types) != len(items):
            raise ValueError(f"{name}: expected {len(types)} values, got {len(items)}")
        return tuple(t(v) for t, v in zip(types, items))
    if origin is Literal:
        if value not in args:
            raise ValueError(f"{name}: {value!r} not among {args}")
        return value
    if type(None) in args:  # Optional[X]
        if value is None:
            return None
        inner = next(a for a in args if a is not type(None))
        return _coerce(name, inner, value)
    if hint is Path:
        return Path(value)
    if hint in (int, float, str, bool):
        return hint(value)
    return value


def apply_overrides(config: TrainConfig, overrides: dict[str, Any]) -> TrainConfig:
    """A copy of ``config`` with ``{field: value}`` applied (strings are parsed by the field's type)."""
    hints = typing.get_type_hints(TrainConfig, globalns={**globals(), "Path": Path})
    known = {f.name for f in fields(TrainConfig)}
    changes = {}
    for key, value in without_removed_options(overrides).items():
        name = key.replace("-", "_")
        if name not in known:
            raise ValueError(f"unknown training option {key!r}; known: {', '.join(sorted(known))}")
        try:
            changes[name] = _coerce(name, hints[name], value)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{name}: bad value {value!r} ({exc})") from None
    return replace(config, **changes)


def parse_overrides(items: list[str]) -> dict[str, str]:
    """``["batch_size=8", "tasks=left,right"]`` → ``{"batch_size": "8", "tasks": "left,right"}``."""
    out = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"option {item!r}: expected KEY=VALUE")
        key, value = item.split("=", 1)
        out[key.strip()] = value
    return out


def save_config(config: TrainConfig, path: Path) -> None:
    path.write_text(json.dumps(config.to_json(), indent=2) + "\n")


def field_docs() -> dict[str, str]:
    """Each field's docstring (for ``--help`` listings)."""
    import ast
    import inspect

    tree = ast.parse(inspect.getsource(TrainConfig))
    docs: dict[str, str] = {}
    body = tree.body[0].body  # type: ignore[attr-defined]
    for a, b in zip(body, body[1:]):
        if isinstance(a, ast.AnnAssign) and isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant):
            docs[a.target.id] = " ".join(str(b.value.value).split())  # type: ignore[union-attr]
    return docs


__all__ = ["Algo", "DEFAULT_INTERSECTIONS", "REMOVED_OPTIONS", "TrainConfig", "apply_overrides", "field_docs",
           "parse_overrides", "save_config", "without_removed_options"]
