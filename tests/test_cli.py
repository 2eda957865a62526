"""The ``crossroads`` command end to end, through its real entry point."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from support import COLOGNE1_NET, REPO_ROOT


def crossroads(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "crossroads.cli", *args],
        capture_output=True, text=True, cwd=REPO_ROOT, timeout=300,
    )


def test_net_list_prints_the_six_paper_intersections() -> None:
    result = crossroads("net", "list")
    assert result.returncode == 0, result.stderr
    names = result.stdout.split()
    assert len(names) >= 6
    assert names == sorted(names)


def test_net_build_writes_a_sumo_network(tmp_path: Path) -> None:
    name = crossroads("net", "list").stdout.split()[0]
    result = crossroads("net", "build", name, "-o", str(tmp_path))
    assert result.returncode == 0, result.stderr
    out = Path(result.stdout.strip())
    assert out.parent == tmp_path and out.name == f"{name}.net.xml"
    assert "<tlLogic" in out.read_text()


def test_paths_json_has_the_documented_fields(tmp_path: Path) -> None:
    name = crossroads("net", "list").stdout.split()[0]
    plot = tmp_path / "paths.png"
    result = crossroads("paths", name, "--task", "left", "--json", "--plot", str(plot))
    assert result.returncode == 0, result.stderr
    candidates = json.loads(result.stdout)
    assert candidates, "at least one left-turn candidate"
    for c in candidates:
        assert {"id", "task", "entrance_lane", "exit_lane", "control_points", "points",
                "segment", "v_pass", "v_stop", "rho", "max_curvature"} <= set(c)
        assert c["task"] == "left" and 0.0 < c["rho"] < 1.0 and c["max_curvature"] <= 0.16
        assert len(c["control_points"]) == 6
        assert all(len(row) == 5 for row in c["points"])
        assert len(c["segment"]) == len(c["points"]) == len(c["v_pass"]) == len(c["v_stop"])
    assert plot.stat().st_size > 10_000


def test_paths_on_a_real_city_network() -> None:
    result = crossroads("paths", str(COLOGNE1_NET), "--task", "straight")
    assert result.returncode == 0, result.stderr
    assert "candidate" in result.stdout


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("paths", "no_such_place", "--task", "left"), "no intersection 'no_such_place'"),
        (("paths", "missing.net.xml", "--task", "left"), "does not exist"),
        (("net", "build", "nowhere.yaml", "-o", "/tmp/x"), "nowhere.yaml"),
        (("serve", "--max-batches", "0"), "max_concurrent_batches: Input should be greater than or equal to 1"),
        (("serve", "--db", "mysql://x/y"), "is not a database URL Crossroads supports"),
    ],
)
def test_bad_input_gets_one_clear_line(args: tuple[str, ...], message: str) -> None:
    result = crossroads(*args)
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr


def test_bad_task_is_rejected_by_name() -> None:
    result = crossroads("paths", "x", "--task", "backwards")
    assert result.returncode != 0
    assert "--task" in result.stderr


NOMINAL_LEFT = str(REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-left.yaml")


def test_run_prints_a_reproducible_json_result(tmp_path: Path) -> None:
    trace = tmp_path / "episode.trace.npz"
    first = crossroads("run", NOMINAL_LEFT, "--policy", "rule", "--seed", "4", "--json",
                       "--trace", str(trace))
    assert first.returncode == 0, first.stderr
    result = json.loads(first.stdout)
    assert {"outcome", "travel_time_s", "steps", "seed"} <= set(result)
    assert result["seed"] == 4
    assert result["outcome"] in {"passed", "collision", "red_light", "off_road", "timeout"}
    from crossroads.evaluation.trace import Trace

    assert len(Trace.load(trace)) == result["steps"] + 1  # every step plus the final state
    again = crossroads("run", NOMINAL_LEFT, "--seed", "4", "--json")
    assert json.loads(again.stdout) == result


def test_run_human_output() -> None:
    result = crossroads("run", NOMINAL_LEFT, "--seed", "1")
    assert result.returncode == 0, result.stderr
    assert "a_single_lane-left seed 1:" in result.stdout


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("run", NOMINAL_LEFT, "--policy", "telepathy"), "unknown policy 'telepathy'"),
        (("run", NOMINAL_LEFT, "--policy", "missing.pt"), "does not exist"),
        (("run", "nowhere.yaml"), "nowhere.yaml"),
    ],
)
def test_run_bad_input(args: tuple[str, ...], message: str) -> None:
    result = crossroads(*args)
    assert result.returncode == 2, result.stderr
    assert message in result.stderr and "Traceback" not in result.stderr


def test_run_bad_scenario_names_the_field(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("version: 1\nname: bad\nintersection: a_single_lane\ntask: left\n"
                   "traffic: {vehicles_per_hour: -5}\n")
    result = crossroads("run", str(bad))
    assert result.returncode == 2
    assert "traffic.vehicles_per_hour" in result.stderr


def test_net_check_lists_the_movements_and_fails_above_max_offset() -> None:
    from support import SUMO_CROSS_NET, sumo_example

    net = str(sumo_example(SUMO_CROSS_NET))
    listed = crossroads("net", "check", net, "--rho", "0.6")  # the paper's paths: 3.15 m off
    assert listed.returncode == 0, listed.stderr
    flagged = [line for line in listed.stdout.splitlines() if line.startswith("!")]
    assert flagged and all("(left" in line or "(right" in line for line in flagged)  # U-turns: not judged
    assert "movements above 1 m; the farthest 3.15 m" in listed.stdout
    assert "the farthest 2.76 m" in crossroads("net", "check", net).stdout  # the chosen ρ's paths
    strict = crossroads("net", "check", net, "--max-offset", "2")
    assert strict.returncode == 1 and "above --max-offset 2" in strict.stderr
    movements = json.loads(crossroads("net", "check", net, "--json").stdout)
    assert {"from_lane", "to_lane", "turn", "max_m", "mean_m", "above_warning"} <= set(movements[0])
    assert crossroads("net", "check", "c_three_lane", "--max-offset", "0.05").returncode == 0


def test_run_refuses_a_start_that_does_not_fit_as_evaluate_does(tmp_path: Path) -> None:
    """One validation for run, evaluate and the API (scenario.network_checks): the start is
    checked along the road before the lane, and refused naming the longest start that fits."""
    scenario = tmp_path / "far.yaml"
    scenario.write_text(f"version: 1\nname: far\nintersection: {{net: {COLOGNE1_NET}}}\ntask: left\n"
                        "approach: '27115123#3'\nego: {start_distance_m: 500}\n")
    for command in ("run", "evaluate"):
        result = crossroads(command, str(scenario), *(("--db", f"sqlite:///{tmp_path}/r.db") if command == "evaluate" else ()))
        assert result.returncode == 2, (command, result.stdout, result.stderr)
        assert "ego.start_distance_m: 500 m does not fit before the stop line" in result.stderr, command
        assert "at most 84.5 m before the line" in result.stderr and "Traceback" not in result.stderr


def test_paths_refuses_a_turn_no_car_can_make_in_one_line() -> None:
    import sumo

    net = Path(sumo.SUMO_HOME) / "tools" / "game" / "A10KW" / "osm.net.xml"
    result = crossroads("paths", str(net), "--junction", "cluster_1643085231_21432440_32500280_32500282",
                        "--task", "right", "--approach", "222448597#0")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert "no drivable right-turn path" in result.stderr and "tighter than the ego can steer" in result.stderr
