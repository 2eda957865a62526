"""The search space: which parameters of a nominal scenario a search may move, and how far.

A space file (YAML, see ``scenarios/search/`` and ``docs/guide/failure-search.md``)::

    version: 1
    name: c_three_lane-left
    scenario: ../nominal/c_three_lane-left.yaml   # the nominal scenario (or the spec inline)
    failures: [collision, red_light, off_road]     # what counts as a failure
    parameters:                                    # in this order they are shrunk
      - {path: traffic.vehicles_per_hour, low: 200, high: 800}
      - {path: lights.phase, choices: [0, 1, 2, 3]}
    seed: {low: 0, high: 1000000, pool: 16}        # the episodes' scenario seeds

A parameter is a dotted path into the scenario (:data:`PARAMETERS` lists those a search may
move) with a range ``low``..``high`` or a list of ``choices``. The scenario seed (the traffic's
draw) is searched in one of two ways. Without ``pool``, each episode draws its own seed from
``seed`` (uniformly, from the search's seed: :func:`draw_seed`): neighbouring seeds share nothing,
so there is nothing to learn about them. With ``pool: K``, the search first draws K distinct seeds
from the range (:func:`seed_pool`) and the sampler chooses among them like any other choice, so it
can learn which traffic makes the policy fail and come back to it with other lights, starts and
behaviours. :func:`scenario_for` makes the scenario of one point of the space: the nominal one with
those values, ``runs: 1`` and that seed, so that ``crossroads evaluate`` on it runs that episode.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from crossroads.sim.abnormal import INJECTED_HEADWAY_S
from crossroads.scenario.spec import (
    MAX_SEED,
    ScenarioSpec,
    load_scenario,
    net_path,
    validate_scenario,
)
from crossroads.validation import FieldProblem, SpecError, load_yaml, validate_model

SPACE_VERSION = 1
FAILURE_OUTCOMES = ("collision", "red_light", "off_road")
SEED_STREAM = 1  # spawn key of the trials' scenario seeds (the engine's samplers use 0)
SEED_POOL_STREAM = 2  # spawn key of a space's pool of seeds
MAX_SEED_POOL = 10_000  # seeds a pool may hold (a choice among more teaches the sampler nothing)
SEED_KEY = "seed"  # the sampler's name for the pooled seed (not a scenario field: no dot)

# The scenario fields a search may move: path → (type, its value when the scenario leaves it or
# its group out, and the value that leaves it out). Abnormal behaviours absent from the nominal
# scenario count as share 0; a light phase left out counts as 0 (on the catalogue's intersections
# the ego's green, what a scenario without one gets), so shrinking it to 0 leaves it out again.
PARAMETERS: dict[str, tuple[type, float | None]] = {
    "ego.start_distance_m": (float, None),
    "ego.start_speed_mps": (float, None),
    "lights.phase": (int, 0),
    "lights.elapsed_s": (float, None),
    "traffic.vehicles_per_hour": (float, None),
    "traffic.cyclists_per_hour": (float, None),
    "traffic.pedestrians_per_hour": (float, None),
    "abnormal.overspeed.share": (float, 0.0),
    "abnormal.overspeed.excess": (float, 0.0),
    "abnormal.rounding.share": (float, 0.0),
    "abnormal.injection.count": (int, 0),
    "abnormal.injection.arrive_s": (float, 0.0),
    "abnormal.injection.excess": (float, 0.0),
    "abnormal.injection.headway_s": (float, INJECTED_HEADWAY_S),
    "warmup_s": (float, None),
}
# What a group the nominal scenario leaves out holds when a search moves one of its fields: the
# values that leave the behaviour out, except that an injection moved into a scenario without one
# injects one vehicle (its count, when the space moves it too, is then set to the proposed value).
_NEW_GROUPS: dict[str, dict[str, float | int]] = {
    "overspeed": {"share": 0.0, "excess": 0.0},
    "rounding": {"share": 0.0},
    "injection": {"count": 1, "arrive_s": 0.0, "excess": 0.0, "headway_s": INJECTED_HEADWAY_S},
}

_CONFIG = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


class Parameter(BaseModel):
    """One parameter: a range (``low``..``high``, ``integer`` for whole numbers) or ``choices``."""

    model_config = _CONFIG

    path: str = Field(description=f"Scenario field to move: one of {', '.join(PARAMETERS)}.")
    low: float | None = Field(default=None, description="Lowest value (with high).")
    high: float | None = Field(default=None, description="Highest value (with low).")
    integer: bool = Field(default=False, description="Whole numbers only (a range of integers).")
    choices: list[float] | None = Field(
        default=None, min_length=1, description="The values it may take, instead of a range.")

    @field_validator("path")
    @classmethod
    def _known(cls, value: str) -> str:
        if value not in PARAMETERS:
            raise ValueError(f"unknown parameter; a search can move {', '.join(PARAMETERS)}")
        return value

    @model_validator(mode="after")
    def _range_or_choices(self) -> Parameter:
        if self.choices is not None:
            if self.low is not None or self.high is not None:
                raise FieldProblem("choices", "give either choices or low/high, not both")
            if len(set(self.choices)) != len(self.choices):
                raise FieldProblem("choices", "the choices repeat a value")
        else:
            if self.low is None or self.high is None:
                raise FieldProblem("low", "give low and high (or choices)")
            if not self.low < self.high:
                raise FieldProblem("high", f"must be above low ({self.low:g})")
        whole = self.integer or PARAMETERS[self.path][0] is int
        values = self.choices if self.choices is not None else [self.low, self.high]
        if whole and any(not float(v).is_integer() for v in values if v is not None):
            raise FieldProblem("choices" if self.choices is not None else "low",
                               "this parameter takes whole numbers")
        return self

    @property
    def whole(self) -> bool:
        """Whole numbers only (asked for, or an integer field such as ``lights.phase``)."""
        return self.integer or PARAMETERS[self.path][0] is int

    @property
    def span(self) -> float:
        """The width of the range (of the choices), the unit of the distance from nominal."""
        values = self.choices if self.choices is not None else [self.low, self.high]
        span = max(values) - min(values)  # type: ignore[type-var, operator]
        return float(span) if span > 0 else 1.0

    def cast(self, value: float) -> float | int:
        """``value`` as the scenario field takes it (an int for whole numbers)."""
        return int(round(value)) if self.whole else float(value)


class SeedRange(BaseModel):
    model_config = _CONFIG

    low: int = Field(default=0, ge=0, le=MAX_SEED, description="Smallest scenario seed.")
    high: int = Field(default=1_000_000, ge=0, le=MAX_SEED, description="Largest scenario seed.")
    pool: int | None = Field(
        default=None, ge=2, le=MAX_SEED_POOL,
        description="Search the seed too: the sampler chooses among this many distinct seeds drawn "
                    "from the range (from the search's seed). Left out, every episode draws its own.")

    @model_validator(mode="after")
    def _ordered(self) -> SeedRange:
        if self.high < self.low:
            raise FieldProblem("high", f"must be at least low ({self.low})")
        if self.pool is not None and self.pool > self.high - self.low + 1:
            raise FieldProblem("pool", f"the range {self.low}..{self.high} holds only "
                                       f"{self.high - self.low + 1} seeds")
        return self


class SearchSpace(BaseModel):
    """A space file (format version 1)."""

    model_config = ConfigDict(**_CONFIG, title="Crossroads search space")

    version: Literal[1] = Field(description="Format version of the file; this Crossroads reads 1.")
    name: str = Field(
        min_length=1, max_length=60, pattern=r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$",
        description="Identifier; the failures' scenario names start with it.")
    description: str = Field(default="", description="Free text.")
    scenario: str | dict[str, Any] = Field(
        description="The nominal scenario: a path (relative to the space file) or the spec inline.")
    failures: list[Literal["collision", "red_light", "off_road"]] = Field(
        default_factory=lambda: list(FAILURE_OUTCOMES), min_length=1,
        description="Outcomes that count as failures.")
    parameters: list[Parameter] = Field(min_length=1, description="What may move, in shrinking order.")
    seed: SeedRange = Field(default_factory=SeedRange, description="Range of the episodes' seeds.")

    @field_validator("parameters")
    @classmethod
    def _distinct(cls, value: list[Parameter]) -> list[Parameter]:
        seen: set[str] = set()
        for i, parameter in enumerate(value):
            if parameter.path in seen:
                raise FieldProblem(f"{i}.path", f"{parameter.path} is given twice")
            seen.add(parameter.path)
        return value


@dataclass(frozen=True)
class Space:
    """A validated space with its nominal scenario (net paths made absolute)."""

    space: SearchSpace
    nominal: ScenarioSpec
    base_dir: str | None  # where the space file is (None for one that came inline)

    @property
    def parameters(self) -> list[Parameter]:
        return self.space.parameters

    @property
    def failures(self) -> tuple[str, ...]:
        return tuple(self.space.failures)

    def nominal_values(self) -> dict[str, float | int]:
        """Each parameter's value in the nominal scenario."""
        data = self.nominal.model_dump(mode="json")
        return {p.path: p.cast(_get(data, p.path)) for p in self.parameters}

    def to_json(self) -> dict[str, Any]:
        """The space with the nominal scenario inline: all a stored search needs to go on."""
        data = self.space.model_dump(mode="json")
        data["scenario"] = self.nominal.model_dump(mode="json")
        return data

    def distance(self, params: Mapping[str, float]) -> float:
        """How far ``params`` are from nominal: the sum over the parameters of |value − nominal|
        in units of the parameter's range (a different choice counts 1)."""
        nominal = self.nominal_values()
        total = 0.0
        for p in self.parameters:
            value, base = float(params.get(p.path, nominal[p.path])), float(nominal[p.path])
            if p.choices is not None:
                total += 0.0 if value == base else 1.0
            else:
                total += abs(value - base) / p.span
        return round(total, 6)

    def off_nominal(self, params: Mapping[str, float]) -> list[str]:
        """The parameters whose value in ``params`` is not the nominal one, in the space's order."""
        nominal = self.nominal_values()
        return [p.path for p in self.parameters
                if float(params.get(p.path, nominal[p.path])) != float(nominal[p.path])]


def _get(data: Mapping[str, Any], path: str) -> Any:
    node: Any = data
    for part in path.split("."):
        if node is None:
            return PARAMETERS[path][1]
        node = node.get(part)
    return PARAMETERS[path][1] if node is None else node


def _set(data: dict[str, Any], path: str, value: Any) -> None:
    parts = path.split(".")
    node = data
    for part in parts[:-1]:
        if node.get(part) is None:
            node[part] = dict(_NEW_GROUPS.get(part, {}))
        node = node[part]
    node[parts[-1]] = value


def _has_group(data: Mapping[str, Any], path: str) -> bool:
    node: Any = data
    for part in path.split(".")[:-1]:
        node = node.get(part) if isinstance(node, Mapping) else None
        if node is None:
            return False
    return True


def scenario_for(space: Space, params: Mapping[str, float], *, seed: int, name: str,
                 description: str = "") -> ScenarioSpec:
    """The nominal scenario with ``params`` set, one run, base seed ``seed``, named ``name``.

    Raises :class:`SpecError` naming the parameter when a value makes no valid scenario.
    """
    data = space.nominal.model_dump(mode="json")
    nominal = space.nominal_values()
    values = {p.path: p.cast(params.get(p.path, nominal[p.path])) for p in space.parameters}
    for path, value in values.items():
        if value != _get(data, path):  # only what moved: an absent group stays absent at nominal
            _set(data, path, value)
    for path, value in values.items():  # a group made above holds every value of the space's
        if _has_group(data, path):
            _set(data, path, value)
    data.update(name=name, runs=1, seed=int(seed), description=description or data["description"])
    try:
        return validate_scenario(data, source=f"search space {space.space.name!r}",
                                 check_references=False)
    except SpecError as exc:
        raise SpecError(exc.source, [(f"parameters: {f}", m) for f, m in exc.problems]) from None


def _absolute_net(spec: ScenarioSpec, base_dir: str | Path | None) -> ScenarioSpec:
    """A ``{net: ...}`` intersection with its path made absolute (the failures are written
    elsewhere than the nominal scenario, and must still find their network)."""
    path = net_path(spec, base_dir)
    if path is None or isinstance(spec.intersection, str):
        return spec
    return spec.model_copy(update={"intersection": spec.intersection.model_copy(
        update={"net": str(path.resolve())})})


def validate_space(data: Any, *, source: str = "<data>", base_dir: str | Path | None = None) -> Space:
    """Validate a parsed space (a YAML mapping or an API body); the nominal scenario is loaded
    (a path counts from ``base_dir``) and every parameter's range is checked against it."""
    if not isinstance(data, Mapping):
        raise SpecError(source, [("", "expected a mapping of fields at the top level")])
    space = validate_model(data, SearchSpace, source=source)
    if isinstance(space.scenario, str):
        path = Path(space.scenario).expanduser()
        if not path.is_absolute():
            path = Path(base_dir or Path.cwd()) / path
        if not path.is_file():
            raise SpecError(source, [("scenario", f"scenario file not found: {path}")])
        nominal = _absolute_net(load_scenario(path), path.parent)
    else:
        try:
            nominal = _absolute_net(validate_scenario(space.scenario, source=f"{source}: scenario",
                                                      base_dir=base_dir), base_dir)
        except SpecError as exc:
            raise SpecError(source, [(f"scenario.{f}" if f else "scenario", m)
                                     for f, m in exc.problems]) from None
    resolved = Space(space, nominal, None if base_dir is None else str(base_dir))
    problems: list[tuple[str, str]] = []
    for i, p in enumerate(space.parameters):  # every end of every range must make a scenario
        for value in (p.choices if p.choices is not None else [p.low, p.high]):
            try:
                scenario_for(resolved, {p.path: value}, seed=0, name=space.name)  # type: ignore[dict-item]
            except SpecError as exc:
                message = "; ".join(m for _, m in exc.problems)
                problems.append((f"parameters.{i}", f"{p.path} = {value:g} makes no valid scenario: {message}"))
                break
    if problems:
        raise SpecError(source, problems)
    return resolved


def network_problems_of(space: Space) -> list[tuple[str, str]]:
    """What the nominal scenario's network says against the space: a light phase it does not
    have, a time in a phase beyond its duration, a start that does not fit the lane. Checked at
    the ends of every range (the others at nominal), and every phase choice with the longest
    time in it: a search should not spend its budget on scenarios that cannot run."""
    from crossroads.scenario.network_checks import network_problems

    def ends(p: Parameter) -> list[float]:
        return list(p.choices) if p.choices is not None else [p.low, p.high]  # type: ignore[list-item]

    points: list[tuple[int, dict[str, float]]] = []
    for i, p in enumerate(space.parameters):
        points.extend((i, {p.path: value}) for value in ends(p))
    by_path = {p.path: (i, p) for i, p in enumerate(space.parameters)}
    if "lights.phase" in by_path and "lights.elapsed_s" in by_path:
        i, elapsed = by_path["lights.elapsed_s"]
        longest = max(ends(elapsed))
        points.extend((i, {"lights.phase": phase, "lights.elapsed_s": longest})
                      for phase in ends(by_path["lights.phase"][1]))
    problems: list[tuple[str, str]] = []
    for i, params in points:
        spec = scenario_for(space, params, seed=0, name=space.space.name)
        for field, message in network_problems(spec, space.base_dir):
            problem = (f"parameters.{i}", f"{field} at {params}: {message}")
            if problem not in problems:
                problems.append(problem)
    return problems


def load_space(path: str | Path) -> Space:
    """Read and validate a space file (its ``scenario`` path counts from the file's directory)."""
    path = Path(path)
    return validate_space(load_yaml(path), source=str(path), base_dir=path.parent.resolve())


def draw_seed(space: Space, search_seed: int, number: int) -> int:
    """The scenario seed of trial ``number``: uniform in the space's seed range, from the search's
    seed (the same search seed gives every trial the same seed, whatever the sampler)."""
    import numpy as np

    rng = np.random.default_rng(np.random.SeedSequence(search_seed, spawn_key=(SEED_STREAM, number)))
    low, high = space.space.seed.low, space.space.seed.high
    return int(rng.integers(low, high, endpoint=True))


def seed_pool(space: Space, search_seed: int) -> list[int] | None:
    """The distinct scenario seeds a search chooses among (``seed.pool`` of them, drawn from the
    range and the search's seed, in ascending order), or None when each episode draws its own."""
    import numpy as np

    seeds = space.space.seed
    if seeds.pool is None:
        return None
    rng = np.random.default_rng(np.random.SeedSequence(search_seed, spawn_key=(SEED_POOL_STREAM,)))
    picked = rng.choice(seeds.high - seeds.low + 1, size=seeds.pool, replace=False)
    return sorted(int(seeds.low + k) for k in picked)
