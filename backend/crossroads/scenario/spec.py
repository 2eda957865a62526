"""Scenarios: what a user writes to say "evaluate a policy here, like this, this many times".

A scenario file (YAML, see ``scenarios/README.md``) is validated into a :class:`ScenarioSpec`:
a frozen, hashable pydantic model whose every field carries its unit. It names the intersection,
the ego's task and start, the lights at entry, the traffic, the abnormal behaviours of SPEC §8,
the run count and the base seed. :func:`to_world_config` turns it into the simulation's
:class:`~crossroads.sim.config.WorldConfig`; :func:`run_seeds` derives one seed per run.

Errors are :class:`~crossroads.validation.SpecError`\\ s naming the file and the field
(``abnormal.overspeed.share``), from the same machinery as the intersection specs.

What is *not* checked here, on purpose: whether the task is possible from the approach, whether
``approach`` / ``ego.entrance_lane`` exist, whether the start distance fits on the road and whether
``lights`` exist in the signal program. Those need the built network and are checked by
:mod:`crossroads.scenario.network_checks` (run, evaluate, the API and the studio), and the world.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    field_validator,
    model_validator,
)

from crossroads.constants import (
    CYCLISTS_PER_HOUR_PER_LANE,
    EVALUATION_RUNS,
    OVERSPEED_SHARE,
    PASS_SPEED_FACTOR_OUTSIDE,
    PEDESTRIANS_PER_HOUR_PER_LANE,
    RHO_BEZIER,
    V_LIMIT_MPS,
    VEHICLES_PER_HOUR_PER_LANE,
)
from crossroads.intersections import catalogue
from crossroads.intersections.resolve import NET_SUFFIXES, NetworkNotFoundError, resolve_net
from crossroads.sim.abnormal import INJECTED_HEADWAY_S, MAX_INJECTED, AbnormalConfig, Injection
from crossroads.sim.config import (
    DEFAULT_GRIDLOCK_STAND_S,
    DEFAULT_START_DISTANCE_M,
    DEFAULT_TIMEOUT_S,
    DEFAULT_WARMUP_S,
    EgoStart,
    SignalStart,
    WorldConfig,
)
from crossroads.sim.traffic import DEFAULT_TURN_SHARES, TrafficDemand
from crossroads.validation import FieldProblem, SpecError, load_yaml, validate_model

SCENARIO_VERSION = 1  # the format version this code reads and writes
SUFFIXES = (".yaml", ".yml")
MAX_SEED = 2**63 - 1  # seeds must fit a signed 64-bit integer (SQL BIGINT, JSON consumers)
MAX_RUNS = 10_000  # [-] runs of one batch: its seeds are all derived before the first episode
SEED_MASK = 0x7FFF_FFFF  # run seeds are 31-bit: they fit SUMO's --seed (a C int) everywhere

# Shared by every model: unknown keys are errors (a typo must not silently fall back to a
# default), values are not coerced across types ("yes" is not a bool, 2.5 not an int), NaN and
# infinities are refused, and specs are immutable so they can be hashed and shared freely.
_CONFIG = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


class NetworkRef(BaseModel):
    """An intersection given as a SUMO network file instead of a catalogue name."""

    model_config = _CONFIG

    net: str = Field(
        description="Path to a SUMO network (.net.xml or .net.xml.gz). A relative path is "
        "resolved against the directory of the scenario file (the working directory for "
        "scenarios that come without a file, e.g. from the API).",
        min_length=1,
    )
    junction: str | None = Field(
        default=None,
        description="Id of the signalised junction to use; default: the traffic light nearest "
        "the network's centre.",
    )

    @field_validator("net")
    @classmethod
    def _net_suffix(cls, value: str) -> str:
        if not value.endswith(NET_SUFFIXES):
            raise ValueError(f"must be a SUMO network file ending in {' or '.join(NET_SUFFIXES)}")
        return value


def _intersection_kind(value: Any) -> str | None:
    """Which form of ``intersection`` a value is (a callable discriminator: clean errors)."""
    if isinstance(value, str):
        return "name"
    if isinstance(value, (Mapping, NetworkRef)):
        return "file"
    return None  # neither: pydantic reports the custom error below


IntersectionRef = Annotated[
    Annotated[str, Tag("name")] | Annotated[NetworkRef, Tag("file")],
    Discriminator(
        _intersection_kind,
        custom_error_type="intersection_ref",
        custom_error_message="expected a catalogue name (a string) or a mapping "
        "{net: <path to a .net.xml>, junction: <optional id>}",
    ),
]


class EgoSpec(BaseModel):
    """Where and how fast the ego enters."""

    model_config = _CONFIG

    start_distance_m: float = Field(
        default=DEFAULT_START_DISTANCE_M, gt=0.0, le=1000.0,
        description="[m] Distance of the ego's start before the stop line, along its entrance lane.",
    )
    start_speed_mps: float = Field(
        default=PASS_SPEED_FACTOR_OUTSIDE * V_LIMIT_MPS, ge=0.0, le=40.0,
        description="[m/s] Initial speed; default 0.8·V_limit = 8.33 m/s, the pass-mode cruise "
        "speed outside the intersection (SPEC §1).",
    )
    entrance_lane: str | None = Field(
        default=None,
        description="SUMO lane id to start on; default: the entrance lane of the first candidate path.",
    )


class LightsSpec(BaseModel):
    """The signal program's state when the ego enters (after the warm-up).

    Either ``ego``, the colour the ego's own movement shows, found in the junction's program
    (``sim.signals.phase_for_light``), or ``phase``, an exact index into the program. Neither:
    ``ego: green``, green at the start on any network (phase 0 is so only on the catalogue's).
    """

    model_config = _CONFIG

    ego: Literal["green", "yellow", "red"] | None = Field(
        default=None,
        description="The ego's light at entry: green, yellow or red, from the junction's own "
        "program (default: green, unless phase is given).")
    phase: int | None = Field(
        default=None, ge=0, le=999,
        description="[-] Exact index into the tlLogic's phases instead of ego (on the catalogue's "
        "intersections 0 is the ego's axis green).")
    elapsed_s: float = Field(
        default=0.0, ge=0.0, le=3600.0,
        description="[s] Time already spent in that colour (with ego) or phase (with phase).")
    program: str | None = Field(
        default=None, min_length=1, max_length=100,
        description="programID of the light's program to run, for a net with several (default: "
        "the one SUMO runs, the last in the file).")

    @model_validator(mode="after")
    def _ego_or_phase(self) -> LightsSpec:
        if self.ego is not None and self.phase is not None:
            raise FieldProblem("phase", "give either ego (the ego's colour) or phase (an exact "
                                        "phase), not both")
        return self

    @property
    def ego_light(self) -> Literal["green", "yellow", "red"]:
        """The colour asked for (green when neither ego nor phase is given)."""
        return self.ego or "green"


class TurnShares(BaseModel):
    """Shares of an approach's vehicles by turn (renormalised over the turns it has)."""

    model_config = _CONFIG

    left: float = Field(default=DEFAULT_TURN_SHARES[0], ge=0.0, le=1.0, description="[-] left-turners.")
    straight: float = Field(default=DEFAULT_TURN_SHARES[1], ge=0.0, le=1.0, description="[-] straight on.")
    right: float = Field(default=DEFAULT_TURN_SHARES[2], ge=0.0, le=1.0, description="[-] right-turners.")

    @model_validator(mode="after")
    def _some_traffic(self) -> TurnShares:
        if self.left + self.straight + self.right <= 0.0:
            raise ValueError("at least one share must be > 0")
        return self


class TrafficSpec(BaseModel):
    """Surrounding traffic per entrance lane (SPEC §2: 400 / 100 / 100 per hour)."""

    model_config = _CONFIG

    vehicles_per_hour: float = Field(
        default=VEHICLES_PER_HOUR_PER_LANE, ge=0.0, le=1800.0, description="[veh/h] per entrance lane.")
    cyclists_per_hour: float = Field(
        default=CYCLISTS_PER_HOUR_PER_LANE, ge=0.0, le=1800.0, description="[bicycles/h] per entrance lane.")
    pedestrians_per_hour: float = Field(
        default=PEDESTRIANS_PER_HOUR_PER_LANE, ge=0.0, le=3600.0, description="[pedestrians/h] per entrance lane.")
    turn_shares: TurnShares | None = Field(
        default_factory=TurnShares,
        description="How an approach's vehicles (per entrance lane × its lanes) split over the turns; "
        "null: every entrance lane its own rate, split evenly over that lane's turns.")
    cyclist_left_turns: bool = Field(
        default=False,
        description="Whether cyclists turn left (across every lane, as SUMO models it); by default "
        "they ride straight on or right, since direct left turns gridlocked the junction.")


class OverspeedSpec(BaseModel):
    """SPEC §8 case 1: some vehicles of the opposite straight lane exceed the speed limit."""

    model_config = _CONFIG

    share: float = Field(
        default=OVERSPEED_SHARE, ge=0.0, le=1.0,
        description="[-] Fraction 0..1 of the opposite straight vehicles that over-speed (paper: 0.15).",
    )
    excess: float = Field(
        ge=0.0, le=1.0, description="[-] Fraction by which they exceed the limit: 0.1 = +10 % (paper: 0.1, 0.2, 0.5).")


class RoundingSpec(BaseModel):
    """SPEC §8 case 2: some left-turners violate the lane connection and cut into the inside lane."""

    model_config = _CONFIG

    share: float = Field(
        ge=0.0, le=1.0,
        description="[-] Fraction 0..1 of the candidate left-turners that cut the corner (paper: 0.1, 0.2, 0.5).",
    )


class InjectionSpec(BaseModel):
    """Over-speeders put on the opposite approach's innermost straight lane at a chosen time, so a
    scenario (or a failure search) can time them against the ego's turn: the first is due at its
    stop line ``arrive_s`` after the episode starts (at its own speed, if nothing holds it up),
    each next one ``headway_s`` later. They come on top of the drawn traffic, which stays the same."""

    model_config = _CONFIG

    count: int = Field(default=1, ge=0, le=MAX_INJECTED, description="[-] How many (0: none).")
    arrive_s: float = Field(
        ge=0.0, le=3600.0,
        description="[s] When the first is due at the opposite stop line, after the episode starts.")
    excess: float = Field(
        default=0.0, ge=0.0, le=1.0,
        description="[-] Fraction by which they exceed the speed limit: 0.5 = +50 % (0: at the limit).")
    headway_s: float = Field(
        default=INJECTED_HEADWAY_S, ge=0.5, le=60.0, description="[s] Time between two of them.")


class AbnormalSpec(BaseModel):
    """Abnormal behaviours of the surrounding traffic; absent = none (only the §8 speed limits)."""

    model_config = _CONFIG

    overspeed: OverspeedSpec | None = Field(default=None, description="Over-speeding, or none.")
    rounding: RoundingSpec | None = Field(default=None, description="Lane-connection violations, or none.")
    injection: InjectionSpec | None = Field(
        default=None, description="Over-speeders timed against the ego, or none.")


class ScenarioSpec(BaseModel):
    """One evaluation scenario (format version 1). Every field has a default except
    ``version``, ``name``, ``intersection`` and ``task``."""

    model_config = ConfigDict(
        **_CONFIG,
        title="Crossroads scenario",
        json_schema_extra={"$schema": "https://json-schema.org/draft/2020-12/schema"},
    )

    version: Literal[1] = Field(description="[-] Format version of the file; this Crossroads reads 1.")
    name: str = Field(
        min_length=1, max_length=100, pattern=r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$",
        description="Identifier (letters, digits, '_', '.', '-'): used in file names, URLs and reports.",
    )
    description: str = Field(default="", max_length=10_000, description="Free text: what the scenario tests and why.")
    intersection: IntersectionRef = Field(
        description="A catalogue name (scenarios/intersections/<name>.yaml, e.g. 'c_three_lane') "
        "or {net: path to a .net.xml, junction: optional junction id}.",
    )
    task: Literal["left", "straight", "right"] = Field(description="The ego's movement through the junction.")
    approach: str | None = Field(
        default=None, description="Incoming edge id the ego comes from; default: the approach from the south.")
    ego: EgoSpec = Field(default_factory=EgoSpec, description="The ego's start.")
    lights: LightsSpec = Field(default_factory=LightsSpec, description="The signal state at entry.")
    traffic: TrafficSpec = Field(default_factory=TrafficSpec, description="Traffic demand.")
    abnormal: AbnormalSpec = Field(default_factory=AbnormalSpec, description="Abnormal behaviours (SPEC §8).")
    warmup_s: float = Field(
        default=DEFAULT_WARMUP_S, ge=0.0, le=600.0,
        description="[s] SUMO runs this long before the ego enters, to fill the junction.")
    timeout_s: float = Field(
        default=DEFAULT_TIMEOUT_S, gt=0.0, le=3600.0,
        description="[s] Ego time after which an unfinished episode counts as a timeout.")
    gridlock_stand_s: float | None = Field(
        default=DEFAULT_GRIDLOCK_STAND_S, gt=0.0, le=3600.0,
        description="[s] A participant other than the ego that stands this long inside the junction "
        "(on an internal lane or a crossing) is removed, and the removal is an episode event; "
        "null turns this gridlock breaker off.")
    standing_ego_courtesy: bool = Field(
        default=True,
        description="Pedestrians, cyclists and drivers stop rather than walk, ride or drive into the ego "
        "while it stands, and a cyclist held 8 s goes round it (is removed, an episode event) "
        "(sim/courtesy.py); false keeps SUMO's, who walk their crossings and ride their lanes whatever "
        "stands across them.")
    junction_clearing: bool = Field(
        default=True,
        description="A vehicle (not the ego) still inside the junction when its movement's light is no "
        "longer green drives on regardless of the junction's right of way, keeping its distance to "
        "whoever is ahead (sim/clearing.py); false keeps SUMO's, whose left-turners then went on "
        "yielding inside the junction into the cross street's green.")
    let_out: bool = Field(
        default=True,
        description="Drivers about to enter the junction on green wait before their stop line for a "
        "vehicle caught inside it (the ego included) whose remaining way they would cross, for at most "
        "20 s after it was caught, when they can still stop comfortably (sim/letting_out.py); false "
        "keeps SUMO's, whose cross street enters across a left-turner clearing the junction. Needs "
        "junction_clearing.")
    junction_lane_changes: bool = Field(
        default=False,
        description="SUMO's drivers may change lanes inside the junction, between the parallel internal "
        "lanes of one movement: SUMO's own, where a change is a sideways jump of a lane's width in one "
        "step that no one sees coming; false (the default) forbids it, as traffic rules do.")
    runs: int = Field(default=EVALUATION_RUNS, ge=1, le=MAX_RUNS, description="[-] Episodes per policy (paper: 200).")
    seed: int = Field(
        default=0, ge=0, le=MAX_SEED,
        description="[-] Base seed; the run seeds are derived from it (see run_seeds), so every "
        "policy meets the same traffic.")
    perception_noise: bool = Field(
        default=True, description="Add the Gaussian perception noise of SPEC §3 to the observations.")
    rho: float | None = Field(
        default=None, gt=0.0, lt=1.0,
        description="[-] ρ of the Bezier candidate paths, in (0, 1), for every path (the paper's "
        f"construction: {RHO_BEZIER}); default: chosen per path so that it stays within the ego's "
        "steering limit (planning.curves).")

    @field_validator("version", mode="before")
    @classmethod
    def _known_version(cls, value: Any) -> Any:
        # A plainer message than pydantic's "Input should be 1": say what this code reads.
        if value != SCENARIO_VERSION or isinstance(value, bool):
            raise ValueError(
                "unsupported scenario format version; this Crossroads reads version "
                f"{SCENARIO_VERSION}")
        return value


# --- loading and checking -----------------------------------------------------------------------


def _untag(field: str) -> str:
    """Drop the union tag pydantic puts into locations (``intersection.file.net`` → ``intersection.net``)."""
    for tag in ("file", "name"):
        prefix = f"intersection.{tag}"
        if field == prefix:
            return "intersection"
        if field.startswith(prefix + "."):
            return "intersection." + field[len(prefix) + 1:]
    return field


def net_path(spec: ScenarioSpec, base_dir: str | Path | None = None) -> Path | None:
    """The network file of a ``{net: ...}`` intersection, made absolute against ``base_dir``
    (default: the working directory); ``None`` for a catalogue name."""
    if isinstance(spec.intersection, str):
        return None
    path = Path(spec.intersection.net).expanduser()
    if not path.is_absolute():
        path = Path(base_dir or Path.cwd()) / path
    return path


def reference_problems(spec: ScenarioSpec, base_dir: str | Path | None = None) -> list[tuple[str, str]]:
    """What the spec names that does not exist: an unknown catalogue name or a missing net file.

    Cheap (no netconvert): a catalogue name is looked up in the catalogue directory.
    """
    if isinstance(spec.intersection, str):
        known = catalogue.list_intersections()
        if spec.intersection not in known:
            return [("intersection", f"unknown intersection {spec.intersection!r}; known: "
                     f"{', '.join(known) or 'none'} (or give {{net: <file.net.xml>}})")]
        return []
    path = net_path(spec, base_dir)
    assert path is not None
    if not path.is_file():
        return [("intersection.net", f"SUMO network file not found: {path}")]
    return []


def validate_scenario(data: Any, *, source: str = "<data>",
                      base_dir: str | Path | None = None, check_references: bool = True) -> ScenarioSpec:
    """Validate parsed data (a YAML mapping or an API body) into a :class:`ScenarioSpec`.

    With ``check_references`` the intersection must exist (see :func:`reference_problems`).
    Raises :class:`SpecError` naming ``source`` and every faulty field.
    """
    if not isinstance(data, Mapping):
        kind = "an empty file" if data is None else f"a {type(data).__name__}"
        raise SpecError(source, [("", f"expected a mapping of fields at the top level, got {kind}")])
    try:
        spec = validate_model(data, ScenarioSpec, source=source)
    except SpecError as exc:
        raise SpecError(exc.source, [(_untag(f), m) for f, m in exc.problems]) from None
    if check_references:
        problems = reference_problems(spec, base_dir)
        if problems:
            raise SpecError(source, problems)
    return spec


def load_scenario(path: str | Path, *, check_references: bool = True) -> ScenarioSpec:
    """Read and validate one scenario file; relative net paths count from its directory."""
    path = Path(path)
    return validate_scenario(load_yaml(path), source=str(path), base_dir=path.parent,
                             check_references=check_references)


def load_scenarios(path_or_dir: str | Path) -> list[tuple[Path, ScenarioSpec]]:
    """A file → ``[(file, spec)]``; a directory → every ``*.yaml``/``*.yml`` in it (not below),
    sorted by file name. The first invalid file raises its :class:`SpecError`."""
    root = Path(path_or_dir)
    if root.is_dir():
        files = sorted(p for p in root.iterdir() if p.is_file() and p.suffix in SUFFIXES)
    else:
        files = [root]
    return [(f, load_scenario(f)) for f in files]


def scenario_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a scenario, for the API and the editor."""
    return ScenarioSpec.model_json_schema(mode="validation")


def canonical_json(spec: ScenarioSpec) -> str:
    """Canonical JSON of a spec: every field (defaults filled in), sorted keys, no spaces.

    Two files that differ only in layout, key order, or in stating a default explicitly give the
    same text. A ``{net: ...}`` path enters as written (not the file's content). A field added
    after scenarios were stored (:data:`_ADDED_LATER`) is left out while it has the value it
    had implicitly before (none, or its default), so that those scenarios keep their identity.
    """
    data = spec.model_dump(mode="json")
    for *groups, name, before in _ADDED_LATER:
        node = data
        for group in groups:
            node = node[group]
        if node.get(name) == before:
            del node[name]
    return json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


# (group..., field, value): a field added later, left out of the identity while it has that value
_ADDED_LATER = (("abnormal", "injection", None), ("junction_clearing", True), ("let_out", True),
                ("junction_lane_changes", False))


def content_hash(spec: ScenarioSpec) -> str:
    """SHA-256 (hex) of :func:`canonical_json`: the scenario's identity in the store.

    Every field counts, name and description included: a renamed scenario is a new scenario.
    """
    return hashlib.sha256(canonical_json(spec).encode("utf-8")).hexdigest()


# --- towards the simulation -------------------------------------------------------------------


def run_seeds(spec: ScenarioSpec, n: int | None = None) -> list[int]:
    """The seeds of runs 0..n-1 (default ``spec.runs``), derived from ``spec.seed``.

    Run ``i`` gets the first 32-bit word of ``SeedSequence(seed, spawn_key=(i,))`` — exactly the
    ``i``-th child of ``SeedSequence(seed).spawn(...)`` — masked to 31 bits so it is a valid SUMO
    seed. Hence: the same base seed gives the same list for every policy (they meet the same
    traffic, run by run), runs are statistically independent, and the seeds of ``k`` runs are
    the first ``k`` seeds of ``n > k`` runs (adding runs never changes the earlier ones).
    """
    count = spec.runs if n is None else n
    if count < 0:
        raise ValueError(f"n must be >= 0, got {count}")
    return [
        int(np.random.SeedSequence(spec.seed, spawn_key=(i,)).generate_state(1, np.uint32)[0]) & SEED_MASK
        for i in range(count)
    ]


def abnormal_config(spec: ScenarioSpec) -> AbnormalConfig:
    """The simulation's :class:`AbnormalConfig` of a spec (the §8 speed limits always apply)."""
    ab = spec.abnormal
    return AbnormalConfig(
        overspeed_share=ab.overspeed.share if ab.overspeed else 0.0,
        overspeed_excess=ab.overspeed.excess if ab.overspeed else 0.0,
        rounding_share=ab.rounding.share if ab.rounding else 0.0,
        injection=None if ab.injection is None or ab.injection.count == 0 else Injection(
            count=ab.injection.count, arrive_s=ab.injection.arrive_s, excess=ab.injection.excess,
            headway_s=ab.injection.headway_s),
    )


def to_world_config(spec: ScenarioSpec, base_dir: str | Path | None = None) -> WorldConfig:
    """The :class:`WorldConfig` of a spec. Resolves the network through
    :func:`crossroads.intersections.resolve.resolve_net` (a catalogue name is built by netconvert, cached);
    a relative net path counts from ``base_dir`` (the scenario file's directory; default: cwd).

    Raises :class:`SpecError` (field ``intersection``) when the network cannot be found.
    """
    source = f"scenario {spec.name!r}"
    problems = reference_problems(spec, base_dir)
    if problems:
        raise SpecError(source, problems)
    if isinstance(spec.intersection, str):
        ref: str | Path = spec.intersection
        junction_id = None
        field = "intersection"
    else:
        ref = net_path(spec, base_dir)  # type: ignore[assignment]
        junction_id = spec.intersection.junction
        field = "intersection.net"
    try:
        net_file = resolve_net(ref)
    except NetworkNotFoundError as exc:
        raise SpecError(source, [(field, str(exc))]) from None
    t = spec.traffic
    return WorldConfig(
        net_file=net_file,
        task=spec.task,
        junction_id=junction_id,
        approach=spec.approach,
        demand=TrafficDemand(
            t.vehicles_per_hour, t.cyclists_per_hour, t.pedestrians_per_hour,
            cyclist_left_turns=t.cyclist_left_turns,
            turn_shares=None if t.turn_shares is None else (
                t.turn_shares.left, t.turn_shares.straight, t.turn_shares.right)),
        abnormal=abnormal_config(spec),
        signal_start=SignalStart(phase_index=spec.lights.phase, elapsed_s=spec.lights.elapsed_s,
                                 ego_light=spec.lights.ego_light, program_id=spec.lights.program),
        ego_start=EgoStart(distance_to_stop_line_m=spec.ego.start_distance_m,
                           speed_mps=spec.ego.start_speed_mps,
                           entrance_lane=spec.ego.entrance_lane),
        warmup_s=spec.warmup_s,
        timeout_s=spec.timeout_s,
        gridlock_stand_s=spec.gridlock_stand_s,
        junction_clearing=spec.junction_clearing,
        let_out=spec.let_out,
        junction_lane_changes=spec.junction_lane_changes,
        standing_ego_courtesy=spec.standing_ego_courtesy,
        perception_noise=spec.perception_noise,
        rho=spec.rho,
    )
