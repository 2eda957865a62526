"""IntersectionSpec: validation (every error names its field), turn geometry, lane links, signals."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crossroads.constants import CROSS_GREEN_S, GREEN_S, YELLOW_S
from crossroads.intersections.spec import IntersectionSpec, relative_turn_deg
from crossroads.validation import SpecError, load_yaml_model, validate_model

ALL = ["right", "straight", "left"]


def four_way(**overrides: Any) -> dict[str, Any]:
    """Raw data of a regular single-lane four-way junction, as a YAML file would hold it."""
    data: dict[str, Any] = {
        "name": "test_four_way",
        "approaches": [
            {"name": leg, "bearing_deg": b, "entrance_lanes": [{"turns": list(ALL)}], "exit_lanes": 1}
            for leg, b in (("south", 180), ("east", 90), ("north", 0), ("west", 270))
        ],
    }
    data.update(overrides)
    return data


def problem_fields(data: dict[str, Any]) -> tuple[str, ...]:
    with pytest.raises(SpecError) as info:
        validate_model(data, IntersectionSpec, source="bad.yaml")
    assert "bad.yaml" in str(info.value)
    return info.value.fields


def test_valid_spec_and_defaults() -> None:
    spec = IntersectionSpec.model_validate(four_way())
    assert spec.ego_approach.name == "south"
    south = spec.approach("south")
    assert south.lane_width_m == 3.5 and south.crossing and south.median_width_m == 0.0
    assert spec.turn_targets("south") == {"straight": "north", "right": "east", "left": "west"}
    assert spec.candidate_counts() == {"left": 1, "straight": 1, "right": 1}
    with pytest.raises(Exception):
        spec.name = "other"  # frozen


def test_default_signal_program_is_spec_section_2() -> None:
    spec = IntersectionSpec.model_validate(four_way())
    first, second = spec.signal_phases
    assert set(first.green_legs) == {"south", "north"} and (first.green_s, first.yellow_s) == (GREEN_S, YELLOW_S)
    assert set(second.green_legs) == {"east", "west"} and second.green_s == CROSS_GREEN_S
    assert spec.cycle_s == pytest.approx(GREEN_S + YELLOW_S + 40.0)


def test_turn_classification_of_skewed_legs() -> None:
    data = four_way()
    for leg, bearing in zip(data["approaches"], (185, 80, 0, 265)):
        leg["bearing_deg"] = bearing
    spec = IntersectionSpec.model_validate(data)
    assert spec.turn_targets("south") == {"straight": "north", "right": "east", "left": "west"}
    assert spec.turn_targets("east") == {"straight": "west", "right": "north", "left": "south"}
    assert relative_turn_deg(180, 90) == pytest.approx(90.0)  # south -> east: right
    assert relative_turn_deg(180, 270) == pytest.approx(-90.0)


def test_single_lane_reaches_every_target_lane() -> None:
    """Fig. 2(f): one left lane into three exit lanes gives three candidates; lanes never cross."""
    data = four_way()
    data["approaches"][0]["entrance_lanes"] = [
        {"turns": ["right"]}, {"turns": ["straight"]}, {"turns": ["straight"]}, {"turns": ["left"]}]
    data["approaches"][2]["exit_lanes"] = 2  # north: straight target
    data["approaches"][3]["exit_lanes"] = 3  # west: left target
    spec = IntersectionSpec.model_validate(data)
    assert spec.candidate_counts() == {"right": 1, "straight": 2, "left": 3}
    left = [(k.from_lane, k.to_lane) for k in spec.lane_links() if k.from_leg == "south" and k.turn == "left"]
    assert left == [(3, 0), (3, 1), (3, 2)]
    straight = [(k.from_lane, k.to_lane) for k in spec.lane_links() if k.from_leg == "south" and k.turn == "straight"]
    assert straight == [(1, 0), (2, 1)]


def test_t_junction_without_straight() -> None:
    data = four_way()
    del data["approaches"][2]  # no north leg
    data["approaches"][0]["entrance_lanes"] = [{"turns": ["right", "left"]}]
    data["approaches"][1]["entrance_lanes"] = [{"turns": ["straight", "left"]}]  # east
    data["approaches"][2]["entrance_lanes"] = [{"turns": ["right", "straight"]}]  # west
    spec = IntersectionSpec.model_validate(data)
    assert spec.turn_targets("south") == {"right": "east", "left": "west"}
    assert [p.green_legs for p in spec.signal_phases] == [("south",), ("east", "west")]


@pytest.mark.parametrize(
    ("mutate", "field", "words"),
    [
        (lambda d: d["approaches"][1].update(name="south"), "approaches.1.name", "used twice"),
        (lambda d: d["approaches"][1].update(bearing_deg=170), "approaches.1.bearing_deg", "apart"),
        (lambda d: d["approaches"][1].update(bearing_deg=400), "approaches.1.bearing_deg", "less than 360"),
        (lambda d: d["approaches"][0].update(colour="red"), "approaches.0.colour", "not permitted"),
        (lambda d: d["approaches"][2]["entrance_lanes"][0].update(turns=["uturn"]),
         "approaches.2.entrance_lanes.0.turns.0", "left"),
        (lambda d: d["approaches"][2]["entrance_lanes"][0].update(turns=[]),
         "approaches.2.entrance_lanes.0.turns", "at least 1"),
        (lambda d: d["approaches"][0].update(exit_lanes=0), "approaches.0.exit_lanes", "greater than"),
        (lambda d: d["approaches"][0].update(sidewalk_width_m=0), "approaches.0.crossing", "sidewalk"),
        (lambda d: d["approaches"][0].update(
            entrance_lanes=[{"turns": ["left"]}, {"turns": ["straight"]}]),
         "approaches.0.entrance_lanes.1.turns", "cross"),
        (lambda d: d.update(approaches=d["approaches"][:2]), "approaches", "at least 3"),
        (lambda d: d.update(phases=[{"green_legs": ["south", "nowhere"], "green_s": 30}]),
         "phases.0.green_legs.1", "unknown leg"),
        (lambda d: d.update(phases=[{"green_legs": ["south"], "green_s": 30}]), "phases", "never get green"),
        (lambda d: d.update(expected_candidates={"left": 3}), "expected_candidates.left", "give 1"),
        (lambda d: d.update(name="Bad Name"), "name", "pattern"),
    ],
)
def test_bad_specs_name_the_field(mutate, field: str, words: str) -> None:
    data = copy.deepcopy(four_way())
    mutate(data)
    with pytest.raises(SpecError) as info:
        validate_model(data, IntersectionSpec, source="bad.yaml")
    assert field in info.value.fields, str(info.value)
    assert words in str(info.value)


def test_turn_without_target_leg_names_the_turn() -> None:
    data = four_way()
    del data["approaches"][2]  # no north leg: straight from the south is impossible
    assert "approaches.0.entrance_lanes.0.turns.1" in problem_fields(data)


def test_load_yaml_model_errors(tmp_path: Path) -> None:
    missing = tmp_path / "nope.yaml"
    with pytest.raises(SpecError, match="nope.yaml.*\n.*file not found"):
        load_yaml_model(missing, IntersectionSpec)

    broken = tmp_path / "broken.yaml"
    broken.write_text("name: x\napproaches: [\n  - {name: south\n")
    with pytest.raises(SpecError, match=r"broken.yaml(.|\n)*YAML syntax error at line \d+"):
        load_yaml_model(broken, IntersectionSpec)

    listing = tmp_path / "list.yaml"
    listing.write_text("- a\n- b\n")
    with pytest.raises(SpecError, match="expected a mapping"):
        load_yaml_model(listing, IntersectionSpec)

    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\napproaches:\n  - {name: south, bearing_deg: 180, exit_lanes: 1,"
                   " entrance_lanes: [{turns: [right, sideways]}]}\n")
    with pytest.raises(SpecError) as info:
        load_yaml_model(bad, IntersectionSpec)
    message = str(info.value)
    assert str(bad) in message and "approaches.0.entrance_lanes.0.turns.1" in message and "sideways" in message


@given(
    n_lanes=st.integers(1, 4), exits=st.integers(1, 5), turn=st.sampled_from(["right", "straight", "left"]),
)
@settings(max_examples=40, deadline=None)
def test_lane_links_reach_every_exit_lane_without_crossing(n_lanes: int, exits: int, turn: str) -> None:
    data = four_way()
    data["approaches"][0]["entrance_lanes"] = [{"turns": [turn]} for _ in range(n_lanes)]
    for leg in data["approaches"][1:]:
        leg["exit_lanes"] = exits
    spec = IntersectionSpec.model_validate(data)
    links = [k for k in spec.lane_links() if k.from_leg == "south"]
    assert spec.candidate_counts() == {turn: exits}
    assert {k.from_lane for k in links} == set(range(n_lanes))  # every lane is used
    pairs = sorted((k.from_lane, k.to_lane) for k in links)
    assert [to for _, to in pairs] == sorted(to for _, to in pairs)  # paths never cross


def test_kerb_radius_is_optional_and_bounded() -> None:
    assert validate_model(four_way(), IntersectionSpec, source="ok.yaml").kerb_radius_m is None
    assert validate_model(four_way(kerb_radius_m=6.0), IntersectionSpec, source="ok.yaml").kerb_radius_m == 6.0
    assert problem_fields(four_way(kerb_radius_m=0.5)) == ("kerb_radius_m",)
    assert problem_fields(four_way(kerb_radius_m=40.0)) == ("kerb_radius_m",)
