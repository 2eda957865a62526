"""The catalogue: the paper's six intersections, lookup by name or path, and the build entry point."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from crossroads.intersections import build as build_module
from crossroads.intersections.catalogue import (
    UnknownIntersectionError, build, intersections_dir, list_intersections, load_spec,
)
from crossroads.validation import SpecError

# Candidate paths of the ego's south approach per task (one per reachable exit lane, SPEC §1).
EXPECTED = {
    "a_single_lane": {"left": 1, "straight": 1, "right": 1},
    "b_two_lane": {"left": 2, "straight": 2, "right": 2},
    "c_three_lane": {"left": 3, "straight": 3, "right": 3},
    "d_irregular_skewed": {"left": 1, "straight": 3, "right": 2},
    "e_irregular_oblique": {"left": 2, "straight": 2, "right": 3},
    "f_irregular_wide": {"left": 3, "straight": 2, "right": 2},  # Fig. 2(f): 3 left, 2 straight
}


def test_list_is_sorted_and_holds_the_six() -> None:
    names = list_intersections()
    assert names == sorted(names)
    assert list(EXPECTED) == [n for n in names if n in EXPECTED]


@pytest.mark.parametrize("name", list(EXPECTED))
def test_six_specs(name: str) -> None:
    spec = load_spec(name)
    assert spec.name == name  # file stem and spec name agree
    assert spec.ego_approach.name == "south"
    assert spec.candidate_counts() == EXPECTED[name] == spec.expected_candidates
    assert all(a.sidewalk_width_m > 0 and a.crossing for a in spec.approaches)


def test_irregular_ones_are_irregular() -> None:
    specs = [load_spec(n) for n in ("d_irregular_skewed", "e_irregular_oblique", "f_irregular_wide")]
    for spec in specs:
        bearings = [a.bearing_deg for a in spec.approaches]
        assert any(b % 90 for b in bearings), spec.name  # some leg off the grid
        assert len({len(a.entrance_lanes) for a in spec.approaches}) > 1, spec.name  # unequal lanes
    assert sum(any(a.median_width_m > 0 for a in s.approaches) for s in specs) == 3


def test_load_by_path() -> None:
    path = intersections_dir() / "b_two_lane.yaml"
    assert load_spec(path) == load_spec("b_two_lane") == load_spec(str(path))


def test_unknown_name_lists_the_known_ones() -> None:
    with pytest.raises(UnknownIntersectionError) as info:
        load_spec("g_nowhere")
    assert "g_nowhere" in str(info.value) and "a_single_lane" in str(info.value)
    with pytest.raises(KeyError):  # also a KeyError for callers that map it to "not found"
        load_spec("g_nowhere")


def test_scenarios_dir_from_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "intersections").mkdir()
    shutil.copy(intersections_dir() / "a_single_lane.yaml", tmp_path / "intersections" / "mine.yaml")
    (tmp_path / "intersections" / "broken.yaml").write_text("name: broken\napproaches: 3\n")
    monkeypatch.setenv("CROSSROADS_SCENARIOS_DIR", str(tmp_path))
    assert list_intersections() == ["broken", "mine"]
    assert load_spec("mine").name == "a_single_lane"
    with pytest.raises(SpecError, match=r"broken.yaml(.|\n)*approaches"):
        load_spec("broken")


def test_build_by_name_uses_the_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CROSSROADS_CACHE_DIR", str(tmp_path))
    net = build("a_single_lane")
    assert net.is_file() and net.is_relative_to(tmp_path)

    def no_netconvert(*args, **kwargs):
        raise AssertionError("netconvert must not run on a cache hit")

    monkeypatch.setattr(build_module.subprocess, "run", no_netconvert)
    assert build("a_single_lane") == net
