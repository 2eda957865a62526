"""What a batch keeps of its network's warnings (scenario/network_checks.py)."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from crossroads.scenario import network_checks
from crossroads.scenario.network_checks import batch_warnings, internal_lane_warning, network_problems
from crossroads.scenario.spec import ScenarioSpec, validate_scenario
from crossroads.planning.routes import PlanningError
from crossroads.validation import SpecError
from support import COLOGNE1_NET, SUMO_CROSS_NET, sumo_example

BS3D_NET = "tools/game/bs3d/bs.net.xml"


def left_turn(intersection: str | dict[str, str], **fields: object) -> ScenarioSpec:
    return validate_scenario({"version": 1, "name": "checked-left", "intersection": intersection,
                              "task": "left", **fields}, check_references=False)


def test_a_batch_on_a_net_whose_internal_lanes_run_off_the_paths_keeps_the_warning(tmp_path: Path) -> None:
    """SUMO's example cross.net.xml: netconvert's left turns run up to 3.1 m from the paper's
    candidate paths (ρ = 0.6). The net has no problems (a batch may run on it), and the batch keeps
    the one warning `crossroads evaluate` prints, relative net paths resolved against base_dir as
    the world does."""
    net = sumo_example(SUMO_CROSS_NET)
    spec = left_turn({"net": str(net)}, rho=0.6)
    assert network_problems(spec) == []
    warnings = batch_warnings(spec)
    assert warnings == [internal_lane_warning(spec)]
    assert "cross.net.xml (left from" in warnings[0] and "crossroads net check" in warnings[0]

    (tmp_path / "cross.net.xml").write_bytes(net.read_bytes())
    assert batch_warnings(left_turn({"net": "cross.net.xml"}, rho=0.6), tmp_path) == warnings
    # the paths the planner chooses (ρ per path) run within 1 m of netconvert's left turns
    assert batch_warnings(left_turn({"net": str(net)})) == []


def test_a_batch_on_a_catalogue_net_keeps_none() -> None:
    """The catalogue's builds draw every internal lane along its candidate path."""
    assert batch_warnings(left_turn("c_three_lane")) == []


def test_a_network_that_cannot_be_measured_still_gets_its_batch(monkeypatch: pytest.MonkeyPatch,
                                                                 caplog: pytest.LogCaptureFixture) -> None:
    """A degenerate shape makes the measurement raise ValueError (PlanningError, JunctionError): the
    batch is created without the warning, and the log says why. No real net found here raises it
    (single-point, repeated-point and NaN internal lanes all measure), so the measurement is
    replaced by one that raises, as PlanningError would."""
    def degenerate(spec: ScenarioSpec, base_dir: object = None) -> str | None:
        raise PlanningError("lane 'x' has a zero-length shape")

    monkeypatch.setattr(network_checks, "internal_lane_warning", degenerate)
    with caplog.at_level(logging.WARNING, logger=network_checks.log.name):
        assert batch_warnings(left_turn("c_three_lane")) == []
    assert "could not measure the internal lanes" in caplog.text and "zero-length shape" in caplog.text


def test_anything_but_an_odd_shape_is_raised(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only ValueError is taken for an odd shape: a bug elsewhere is not hidden as 'no warning'."""
    def broken(spec: ScenarioSpec, base_dir: object = None) -> str | None:
        raise KeyError("lanes")

    monkeypatch.setattr(network_checks, "internal_lane_warning", broken)
    with pytest.raises(KeyError):
        batch_warnings(left_turn("c_three_lane"))


# --- the ego's start and light: one validation for run, evaluate, the API and the studio ----------


def test_the_start_is_checked_along_the_road_before_the_lane() -> None:
    """cologne1's south-west approach: lanes of 41 m, 89 m of road before the stop line. The
    default 40 m starts on the edge before; 500 m is refused, naming the longest start."""
    net = {"net": str(COLOGNE1_NET)}
    assert network_problems(left_turn(net, approach="27115123#3")) == []
    problems = network_problems(left_turn(net, approach="27115123#3", ego={"start_distance_m": 500.0}))
    assert len(problems) == 1 and problems[0][0] == "ego.start_distance_m"
    assert "the road leading to it (27115123#2 -> 27115123#3) is 89.3 m long, so the ego can start at " \
           "most 84.5 m before the line" in problems[0][1]


@pytest.mark.parametrize("light", ["green", "yellow", "red"])
def test_the_ego_s_light_is_found_in_the_junction_s_own_program(light: str) -> None:
    assert network_problems(left_turn("b_two_lane", lights={"ego": light, "elapsed_s": 1.0})) == []


def test_a_light_the_program_never_shows_is_refused_naming_the_programs_that_do() -> None:
    """SUMO's bs3d game net: one static program per stage of the game, SUMO running the last, which
    never shows the ego's movement green."""
    spec = left_turn({"net": str(sumo_example(BS3D_NET))})
    problems = network_problems(spec)
    assert [f for f, _ in problems] == ["lights.ego"]
    assert "is never green: it shows" in problems[0][1]
    assert problems[0][1].endswith("show it green (lights.program)")
    chosen = problems[0][1].rsplit("program(s) '", 1)[1].split("'")[0]
    assert network_problems(left_turn({"net": str(sumo_example(BS3D_NET))}, lights={"program": chosen})) == []
    unknown = network_problems(left_turn({"net": str(sumo_example(BS3D_NET))}, lights={"program": "night"}))
    assert unknown[0][0] == "lights.program" and "has no program 'night'; its programs: '0', '1', '2', '3'" in unknown[0][1]


def test_an_exact_phase_is_still_checked() -> None:
    problems = network_problems(left_turn("b_two_lane", lights={"phase": 99}))
    assert problems[0][0] == "lights.phase"
    with pytest.raises(SpecError, match="give either ego"):
        left_turn("b_two_lane", lights={"phase": 0, "ego": "green"})


def _one_exit_junction(directory: Path) -> Path:
    """A junction C that the south, north and west legs only come into and the east leg only
    leaves: from the south (a right turn), the approach opposite (the north's) can only turn left."""
    import shutil
    import subprocess
    import sys

    netconvert = Path(sys.executable).parent / "netconvert"
    binary = str(netconvert) if netconvert.is_file() else shutil.which("netconvert")
    if binary is None:
        pytest.skip("netconvert is not installed")
    (directory / "tee.nod.xml").write_text(
        '<nodes><node id="C" x="0" y="0" type="traffic_light"/><node id="S" x="0" y="-100"/>'
        '<node id="W" x="-100" y="0"/><node id="N" x="0" y="100"/><node id="E" x="100" y="0"/></nodes>')
    (directory / "tee.edg.xml").write_text(
        '<edges><edge id="SC" from="S" to="C" numLanes="1" speed="13.89"/>'
        '<edge id="NC" from="N" to="C" numLanes="1" speed="13.89"/>'
        '<edge id="WC" from="W" to="C" numLanes="1" speed="13.89"/>'
        '<edge id="CE" from="C" to="E" numLanes="1" speed="13.89"/></edges>')
    net = directory / "tee.net.xml"
    subprocess.run([binary, "-n", str(directory / "tee.nod.xml"), "-e", str(directory / "tee.edg.xml"),
                    "--no-turnarounds", "-o", str(net)], check=True, capture_output=True, timeout=60)
    return net


def test_an_injection_needs_a_straight_lane_on_the_opposite_approach(tmp_path: Path) -> None:
    net = {"net": str(_one_exit_junction(tmp_path))}
    right_turn = {"version": 1, "name": "one-exit", "intersection": net, "task": "right", "approach": "SC"}
    assert network_problems(validate_scenario(right_turn, check_references=False)) == []
    injected = validate_scenario({**right_turn, "abnormal": {"injection": {"arrive_s": 5.0}}},
                                 check_references=False)
    [(field, message)] = network_problems(injected)
    assert field == "abnormal.injection" and "opposite 'SC' ('NC') has no lane going straight" in message
    assert network_problems(left_turn("c_three_lane", abnormal={"injection": {"arrive_s": 5.0}})) == []
