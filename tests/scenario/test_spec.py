"""ScenarioSpec: validation errors that name the field, schema, hashing, seeds, conversion."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from crossroads.scenario.spec import (
    ScenarioSpec,
    abnormal_config,
    canonical_json,
    content_hash,
    load_scenario,
    load_scenarios,
    run_seeds,
    scenario_json_schema,
    to_world_config,
    validate_scenario,
)
from crossroads.intersections.catalogue import list_intersections
from crossroads.validation import SpecError
from support import REPO_ROOT

MINIMAL: dict[str, Any] = {"version": 1, "name": "t", "intersection": "a_single_lane", "task": "left"}
FULL: dict[str, Any] = {
    "version": 1,
    "name": "full-example",
    "description": "every field",
    "intersection": "c_three_lane",
    "task": "straight",
    "approach": "south_in",
    "ego": {"start_distance_m": 30.0, "start_speed_mps": 5.0, "entrance_lane": "south_in_1"},
    "lights": {"phase": 2, "elapsed_s": 1.5},
    "traffic": {"vehicles_per_hour": 200, "cyclists_per_hour": 0, "pedestrians_per_hour": 50.5},
    "abnormal": {"overspeed": {"share": 0.2, "excess": 0.5}, "rounding": {"share": 0.1}},
    "warmup_s": 30.0,
    "timeout_s": 45.0,
    "runs": 10,
    "seed": 99,
    "perception_noise": False,
    "rho": 0.5,
}


def with_(change: dict[str, Any], base: dict[str, Any] = MINIMAL) -> dict[str, Any]:
    """A copy of ``base`` with dotted keys set (``"ego.start_speed_mps": -1``); None deletes."""
    data = copy.deepcopy(base)
    for dotted, value in change.items():
        *parents, last = dotted.split(".")
        node = data
        for p in parents:
            node = node.setdefault(p, {})
        if value is None:
            node.pop(last, None)
        else:
            node[last] = value
    return data


def write(tmp_path: Path, data: Any, name: str = "s.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data) if not isinstance(data, str) else data)
    return path


# --- good scenarios ---------------------------------------------------------------------------


def test_defaults_are_the_paper_values() -> None:
    spec = validate_scenario(MINIMAL)
    # ρ: None = chosen per candidate path within the ego's steering limit (planning.curves)
    assert spec.runs == 200 and spec.seed == 0 and spec.rho is None and spec.perception_noise
    assert (spec.traffic.vehicles_per_hour, spec.traffic.cyclists_per_hour,
            spec.traffic.pedestrians_per_hour) == (400.0, 100.0, 100.0)
    # the ego's own light green at entry, on any net (phase 0 is green only on the catalogue's)
    assert (spec.lights.ego, spec.lights.phase, spec.lights.elapsed_s) == (None, None, 0.0)
    assert spec.lights.ego_light == "green" and spec.lights.program is None
    cfg = to_world_config(spec)
    assert (cfg.signal_start.phase_index, cfg.signal_start.ego_light, cfg.rho) == (None, "green", None)
    assert spec.ego.start_speed_mps == pytest.approx(0.8 * 37.5 / 3.6)
    assert spec.abnormal.overspeed is None and spec.abnormal.rounding is None


def test_overspeed_share_defaults_to_the_paper_share() -> None:
    spec = validate_scenario(with_({"abnormal": {"overspeed": {"excess": 0.2}}}))
    assert spec.abnormal.overspeed is not None and spec.abnormal.overspeed.share == 0.15


def test_an_injection_converts_and_a_count_of_zero_is_none() -> None:
    spec = validate_scenario(with_({"abnormal": {"injection": {"arrive_s": 7.5, "excess": 0.5}}}))
    injection = abnormal_config(spec).injection
    assert injection is not None
    assert (injection.count, injection.arrive_s, injection.excess, injection.headway_s) == (1, 7.5, 0.5, 2.0)
    none = validate_scenario(with_({"abnormal": {"injection": {"arrive_s": 7.5, "count": 0}}}))
    assert abnormal_config(none).injection is None


def test_full_scenario_converts_field_by_field() -> None:
    spec = validate_scenario(FULL)
    cfg = to_world_config(spec)
    assert cfg.task == "straight" and cfg.approach == "south_in" and cfg.junction_id is None
    assert cfg.net_file.name.endswith(".net.xml") and cfg.net_file.is_file()
    assert (cfg.ego_start.distance_to_stop_line_m, cfg.ego_start.speed_mps,
            cfg.ego_start.entrance_lane) == (30.0, 5.0, "south_in_1")
    assert (cfg.signal_start.phase_index, cfg.signal_start.elapsed_s) == (2, 1.5)
    assert (cfg.demand.vehicles_per_hour, cfg.demand.cyclists_per_hour,
            cfg.demand.pedestrians_per_hour) == (200.0, 0.0, 50.5)
    assert (cfg.abnormal.overspeed_share, cfg.abnormal.overspeed_excess,
            cfg.abnormal.rounding_share) == (0.2, 0.5, 0.1)
    assert (cfg.warmup_s, cfg.timeout_s, cfg.perception_noise, cfg.rho) == (30.0, 45.0, False, 0.5)


def test_net_file_relative_to_the_scenario_file(tmp_path: Path) -> None:
    src = to_world_config(validate_scenario(MINIMAL)).net_file
    (tmp_path / "nets").mkdir()
    (tmp_path / "nets" / "mine.net.xml").write_bytes(src.read_bytes())
    (tmp_path / "scen").mkdir()
    path = write(tmp_path / "scen", with_({"intersection": {"net": "../nets/mine.net.xml",
                                                             "junction": "J9"}}))
    spec = load_scenario(path)
    cfg = to_world_config(spec, path.parent)
    assert cfg.net_file == (tmp_path / "nets" / "mine.net.xml").resolve()
    assert cfg.junction_id == "J9"
    # without the base directory the relative path counts from the working directory: not found
    with pytest.raises(SpecError) as err:
        to_world_config(spec)
    assert err.value.fields == ("intersection.net",)


def test_load_scenarios_of_a_directory_is_sorted(tmp_path: Path) -> None:
    for name in ("b", "a", "c"):
        write(tmp_path, with_({"name": name}), f"{name}.yaml")
    (tmp_path / "notes.txt").write_text("not a scenario")
    loaded = load_scenarios(tmp_path)
    assert [p.name for p, _ in loaded] == ["a.yaml", "b.yaml", "c.yaml"]
    assert [s.name for _, s in loaded] == ["a", "b", "c"]


def test_spec_is_frozen_and_hashable() -> None:
    spec = validate_scenario(FULL)
    with pytest.raises(Exception):
        spec.runs = 3  # type: ignore[misc]
    assert hash(spec) == hash(validate_scenario(copy.deepcopy(FULL)))


# --- bad scenarios: one SpecError naming the field --------------------------------------------


@pytest.mark.parametrize("change, field", [
    ({"runs": "many"}, "runs"),                                     # wrong type
    ({"runs": 2.5}, "runs"),
    ({"runs": 0}, "runs"),
    ({"perception_noise": "yes"}, "perception_noise"),
    ({"name": 12}, "name"),
    ({"name": "has space"}, "name"),
    ({"traffic.vehicles_per_hour": -1}, "traffic.vehicles_per_hour"),  # negative rate
    ({"traffic.pedestrians_per_hour": float("inf")}, "traffic.pedestrians_per_hour"),
    ({"abnormal.overspeed": {"share": 1.5, "excess": 0.1}}, "abnormal.overspeed.share"),  # share > 1
    ({"abnormal.overspeed": {"share": 0.1}}, "abnormal.overspeed.excess"),  # missing
    ({"abnormal.overspeed": {"excess": -0.1}}, "abnormal.overspeed.excess"),
    ({"abnormal.rounding": {"share": -0.1}}, "abnormal.rounding.share"),
    ({"abnormal.injection": {"arrive_s": 5.0, "count": 6}}, "abnormal.injection.count"),
    ({"abnormal.injection": {"count": 1}}, "abnormal.injection.arrive_s"),  # missing
    ({"abnormal.injection": {"arrive_s": 5.0, "headway_s": 0.1}}, "abnormal.injection.headway_s"),
    ({"task": "uturn"}, "task"),                                    # unknown task
    ({"version": 2}, "version"),                                    # unknown version
    ({"version": "1"}, "version"),
    ({"version": None}, "version"),                                 # missing version
    ({"colour": "red"}, "colour"),                                  # extra key
    ({"ego.speed": 3.0}, "ego.speed"),                              # extra nested key
    ({"ego.start_distance_m": 0.0}, "ego.start_distance_m"),
    ({"ego.start_speed_mps": -1.0}, "ego.start_speed_mps"),
    ({"lights.phase": -1}, "lights.phase"),
    ({"lights.elapsed_s": -0.1}, "lights.elapsed_s"),
    ({"lights.ego": "blue"}, "lights.ego"),
    ({"lights.ego": "red", "lights.phase": 2}, "lights.phase"),
    ({"timeout_s": 0.0}, "timeout_s"),
    ({"warmup_s": -5.0}, "warmup_s"),
    ({"seed": -1}, "seed"),
    ({"rho": 1.0}, "rho"),
    ({"rho": 0.0}, "rho"),
    ({"intersection": "nowhere"}, "intersection"),                  # unknown intersection
    ({"intersection": 3}, "intersection"),
    ({"intersection": {"net": "missing.net.xml"}}, "intersection.net"),  # missing net
    ({"intersection": {"net": "a_single_lane.yaml"}}, "intersection.net"),
    ({"intersection": {"net": "x.net.xml", "id": "J"}}, "intersection.id"),
    ({"intersection": {"junction": "J"}}, "intersection.net"),
])
def test_bad_scenario_names_the_field(tmp_path: Path, change: dict[str, Any], field: str) -> None:
    path = write(tmp_path, with_(change))
    with pytest.raises(SpecError) as err:
        load_scenario(path)
    assert field in err.value.fields, str(err.value)
    assert str(path) in str(err.value)


def test_unknown_intersection_lists_the_known_ones() -> None:
    with pytest.raises(SpecError) as err:
        validate_scenario(with_({"intersection": "z_nowhere"}))
    message = str(err.value)
    assert all(name in message for name in list_intersections())


def test_every_problem_is_reported_at_once() -> None:
    with pytest.raises(SpecError) as err:
        validate_scenario(with_({"task": "fly", "runs": -3, "traffic.cyclists_per_hour": -1}))
    assert set(err.value.fields) == {"task", "runs", "traffic.cyclists_per_hour"}


@pytest.mark.parametrize("text, what", [
    ("", "empty"), ("- a\n- b\n", "list"), ("version: [1\n", "YAML syntax"),
])
def test_unreadable_files(tmp_path: Path, text: str, what: str) -> None:
    with pytest.raises(SpecError, match=what):
        load_scenario(write(tmp_path, text))
    with pytest.raises(SpecError, match="not found"):
        load_scenario(tmp_path / "absent.yaml")


# --- schema, hash, seeds --------------------------------------------------------------------


def test_json_schema_covers_every_field() -> None:
    schema = scenario_json_schema()
    json.dumps(schema)
    assert schema["type"] == "object" and schema["additionalProperties"] is False
    assert set(schema["properties"]) == set(ScenarioSpec.model_fields)
    assert set(schema["required"]) == {"version", "name", "intersection", "task"}
    assert schema["properties"]["version"]["const"] == 1
    defs = schema["$defs"]
    for model in ("EgoSpec", "LightsSpec", "TrafficSpec", "OverspeedSpec", "RoundingSpec",
                  "AbnormalSpec", "NetworkRef"):
        assert defs[model]["additionalProperties"] is False
        for name, prop in defs[model]["properties"].items():
            assert prop.get("description"), f"{model}.{name} has no description"
    for name, prop in schema["properties"].items():
        assert prop.get("description"), f"{name} has no description"
    assert defs["OverspeedSpec"]["properties"]["share"]["maximum"] == 1.0
    rho = next(o for o in schema["properties"]["rho"]["anyOf"] if o.get("type") == "number")
    assert rho["exclusiveMaximum"] == 1.0


def test_content_hash_is_canonical_and_sensitive() -> None:
    h = content_hash(validate_scenario(FULL))
    assert len(h) == 64 and int(h, 16) >= 0
    reordered = dict(reversed(list(copy.deepcopy(FULL).items())))
    assert content_hash(validate_scenario(reordered)) == h
    # stating a default explicitly or writing 200 as an int or float changes nothing
    assert content_hash(validate_scenario(MINIMAL)) == content_hash(
        validate_scenario(with_({"runs": 200, "rho": None, "traffic.vehicles_per_hour": 400})))
    for change in ({"seed": 100}, {"runs": 11}, {"abnormal.rounding.share": 0.11}, {"rho": 0.51},
                   {"ego.entrance_lane": "south_in_2"}, {"name": "other"}, {"approach": None},
                   {"abnormal.injection": {"arrive_s": 4.0}}, {"junction_clearing": False},
                   {"let_out": False}, {"junction_lane_changes": True}):
        assert content_hash(validate_scenario(with_(change, FULL))) != h, change
    # a field added later, when none, leaves the identity of the scenarios stored before it as it was
    assert content_hash(validate_scenario(with_({"abnormal.injection": None}, FULL))) == h
    assert '"injection"' not in canonical_json(validate_scenario(FULL))
    # ... and so does one at its default
    assert content_hash(validate_scenario(with_({"junction_clearing": True}, FULL))) == h
    assert '"junction_clearing"' not in canonical_json(validate_scenario(FULL))
    assert content_hash(validate_scenario(with_({"let_out": True}, FULL))) == h
    assert '"let_out"' not in canonical_json(validate_scenario(FULL))
    assert content_hash(validate_scenario(with_({"junction_lane_changes": False}, FULL))) == h


def test_content_hash_is_pinned() -> None:
    # The store keys scenarios by this hash, so it must not drift with library versions. It
    # changes (on purpose) when a default changes: the defaults are part of what a file means.
    spec = validate_scenario(MINIMAL)
    assert content_hash(spec) == (
        "3ab8914943e1abf125c431a9fba9c127e4521e607863d64188981351bc4ae950"), content_hash(spec)


def test_run_seeds_are_deterministic_and_independent_of_the_count() -> None:
    spec = validate_scenario(with_({"seed": 12345, "runs": 50}))
    seeds = run_seeds(spec)
    assert len(seeds) == 50 and seeds == run_seeds(validate_scenario(with_({"seed": 12345, "runs": 50})))
    assert run_seeds(spec, 10) == seeds[:10]
    assert run_seeds(spec, 200)[:50] == seeds
    assert len(set(seeds)) == 50 and all(0 <= s < 2**31 for s in seeds)
    assert run_seeds(validate_scenario(with_({"seed": 12346})), 50) != seeds
    assert run_seeds(spec, 0) == []
    # the documented construction: the i-th child of SeedSequence(seed).spawn(...)
    children = np.random.SeedSequence(12345).spawn(3)
    assert run_seeds(spec, 3) == [int(c.generate_state(1, np.uint32)[0]) & 0x7FFF_FFFF for c in children]


@given(base=st.integers(0, 2**63 - 1), k=st.integers(0, 20), extra=st.integers(0, 20))
def test_run_seeds_prefix_property(base: int, k: int, extra: int) -> None:
    spec = ScenarioSpec.model_validate(with_({"seed": base}))
    assert run_seeds(spec, k + extra)[:k] == run_seeds(spec, k)


def test_readme_example_is_valid() -> None:
    text = (REPO_ROOT / "scenarios" / "README.md").read_text()
    example = text.split("```yaml", 1)[1].split("```", 1)[0]
    spec = validate_scenario(yaml.safe_load(example))
    assert spec.abnormal.overspeed is not None
