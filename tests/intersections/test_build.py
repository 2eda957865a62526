"""build_network: the six intersections build with netconvert, cache, fail cleanly, and carry SPEC §2 signals."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import LineString, Point

from crossroads.intersections import build as build_mod
from crossroads.intersections.build import (
    NetworkBuildError, build_network, cache_key, read_tls_links,
)
from crossroads.intersections.catalogue import list_intersections, load_spec
from crossroads.network.junction import read_junction
from crossroads.intersections.spec import IntersectionSpec
from crossroads.planning.routes import build_candidate

SIX = ["a_single_lane", "b_two_lane", "c_three_lane", "d_irregular_skewed", "e_irregular_oblique",
       "f_irregular_wide"]


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A private build cache for this module (the six are built once, then hit)."""
    root = tmp_path_factory.mktemp("nets")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CROSSROADS_CACHE_DIR", str(root))
        yield root


@pytest.fixture(scope="module")
def nets(cache_dir: Path) -> dict[str, Path]:
    return {name: build_network(load_spec(name)) for name in SIX}


def test_catalogue_holds_the_six() -> None:
    assert set(SIX) <= set(list_intersections())


@pytest.mark.parametrize("name", SIX)
def test_each_intersection_builds_with_pedestrian_structures(nets: dict[str, Path], name: str) -> None:
    spec = load_spec(name)
    net = nets[name]
    root = ET.parse(net).getroot()
    assert [t.get("id") for t in root.iter("tlLogic")] == ["C"]
    junction = next(j for j in root.iter("junction") if j.get("id") == "C")
    assert junction.get("type") == "traffic_light"
    edges = {e.get("id"): e for e in root.iter("edge")}
    crossings = [e for e in edges.values() if e.get("function") == "crossing"]
    walking = [e for e in edges.values() if e.get("function") == "walkingarea"]
    assert len(crossings) == sum(a.crossing for a in spec.approaches)
    assert walking
    for a in spec.approaches:
        for edge_id, n_car in ((a.in_edge, len(a.entrance_lanes)), (a.out_edge, a.exit_lanes)):
            lanes = list(edges[edge_id].iter("lane"))
            assert lanes[0].get("allow") == "pedestrian"  # sidewalk on the right
            has_bike = a.bike_lane_width_m > 0
            assert len(lanes) == 1 + has_bike + n_car
            if has_bike:
                assert lanes[1].get("allow") == "bicycle"
    # no U-turns, and every car link is controlled by the light
    for c in root.iter("connection"):
        assert c.get("dir") != "t"
    # the build left its inputs and log beside the net, nothing half-written
    for f in ("plain.nod.xml", "plain.edg.xml", "plain.con.xml", "program.tll.xml", "build.json"):
        assert (net.parent / f).is_file()
    assert not any(p.name.endswith(".tmp") for p in net.parent.parent.iterdir())


def test_sumo_loads_the_nets_without_warnings(nets: dict[str, Path]) -> None:
    sumo = Path(sys.executable).parent / "sumo"
    for name, net in nets.items():
        proc = subprocess.run([str(sumo), "-n", str(net), "--no-step-log", "true", "-e", "1"],
                              capture_output=True, text=True, check=False)
        assert proc.returncode == 0, proc.stderr
        assert "Warning" not in proc.stderr and "Error" not in proc.stderr, (name, proc.stderr)


def _median_gap(root: ET.Element, in_edge: str, out_edge: str) -> float:
    """[m] clear distance between the innermost car lanes of the two directions of a leg."""
    def inner(edge_id: str) -> tuple[tuple[float, float], float, tuple[float, float]]:
        edge = next(e for e in root.iter("edge") if e.get("id") == edge_id)
        lane = list(edge.iter("lane"))[-1]
        pts = [tuple(map(float, p.split(","))) for p in lane.get("shape", "").split()]
        return pts[0], float(lane.get("width", "0")), pts[-1]
    (a0, wa, a1), (b0, wb, _) = inner(in_edge), inner(out_edge)
    # distance from b0 to the infinite line a0-a1 (the two directions are parallel)
    dx, dy = a1[0] - a0[0], a1[1] - a0[1]
    dist = abs(dx * (b0[1] - a0[1]) - dy * (b0[0] - a0[0])) / math.hypot(dx, dy)
    return dist - wa / 2 - wb / 2


def test_medians_leave_a_gap(nets: dict[str, Path]) -> None:
    checked = 0
    for name, net in nets.items():
        root = ET.parse(net).getroot()
        for a in load_spec(name).approaches:
            assert _median_gap(root, a.in_edge, a.out_edge) == pytest.approx(a.median_width_m, abs=0.05)
            checked += a.median_width_m > 0
    assert checked >= 3


def _program(net: Path) -> list[tuple[float, str]]:
    logic = next(ET.parse(net).getroot().iter("tlLogic"))
    return [(float(p.get("duration", "0")), p.get("state", "")) for p in logic.iter("phase")]


@pytest.mark.parametrize("name", SIX)
def test_signal_program_of_spec_section_2(nets: dict[str, Path], name: str) -> None:
    spec = load_spec(name)
    net = nets[name]
    links = read_tls_links(net.parent)
    program = _program(net)
    assert all(len(state) == len(links) for _, state in program)
    ego = spec.ego_approach.name

    def seconds_in(index: int) -> dict[str, float]:
        out: dict[str, float] = {}
        for duration, state in program:
            out[state[index]] = out.get(state[index], 0.0) + duration
        return out

    straight = [k for k in links if k.leg == ego and k.turn == "straight" and k.kind == "vehicle"]
    assert straight
    for k in straight:
        assert seconds_in(k.link_index) == {"G": 60.0, "y": 3.0, "r": 40.0}
        # walk, pedestrian clearance, yellow, all-red; the cross axis' four stages
        assert [s[k.link_index] for _, s in program] == ["G", "G", "y", "r", "r", "r", "r", "r"]
    for k in links:
        if k.turn == "right":
            assert set(seconds_in(k.link_index)) == {"g"}
    for _, state in program:
        for k in links:
            if k.turn == "left":
                same_leg_straight = [s for s in links if s.leg == k.leg and s.turn == "straight"]
                if same_leg_straight and state[same_leg_straight[0].link_index] == "G":
                    assert state[k.link_index] == "g"
            if k.kind == "crossing":
                parallel = [s for s in links if s.leg == k.leg and s.kind != "crossing" and s.turn != "right"]
                if state[k.link_index] == "G":
                    assert all(state[s.link_index] == "r" for s in parallel)


def test_sumo_runs_the_program(nets: dict[str, Path]) -> None:
    """Run SUMO itself (libsumo, in a child process: one simulation per process) for one cycle."""
    net = nets["a_single_lane"]
    links = read_tls_links(net.parent)
    index = next(k.link_index for k in links if k.leg == "south" and k.turn == "straight")
    script = textwrap.dedent(f"""
        import libsumo
        libsumo.start(["sumo", "-n", {str(net)!r}, "--no-step-log", "true", "--step-length", "1"])
        seen = []
        for _ in range(103):
            libsumo.simulationStep()
            seen.append(libsumo.trafficlight.getRedYellowGreenState("C")[{index}])
        libsumo.close()
        print("".join(seen))
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True, timeout=60)
    seen = proc.stdout.strip().splitlines()[-1]
    # one full cycle sampled every second: 60 s green, then 3 s yellow, then 40 s red
    assert (seen.count("G"), seen.count("y"), seen.count("r")) == (60, 3, 40)
    assert "G" * 59 + "yyy" + "r" * 40 in seen + seen


def test_second_build_hits_the_cache(nets: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    def no_netconvert(*args, **kwargs):
        raise AssertionError("netconvert must not run on a cache hit")

    monkeypatch.setattr(build_mod.subprocess, "run", no_netconvert)
    spec = load_spec("a_single_lane")
    assert build_network(spec) == nets["a_single_lane"]
    info = json.loads((nets["a_single_lane"].parent / "build.json").read_text())
    assert info["key"] == cache_key(spec) == nets["a_single_lane"].parent.name


def test_cache_key_depends_on_the_spec() -> None:
    spec = load_spec("a_single_lane")
    other = spec.model_copy(update={"description": spec.description + " (changed)"})
    assert cache_key(spec) == cache_key(load_spec("a_single_lane"))
    assert cache_key(spec) != cache_key(other)


def test_failed_build_leaves_no_cache_entry(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    fake = tmp_path / "netconvert"
    fake.write_text("#!/bin/sh\necho 'Error: something SUMO did not like' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setattr(build_mod, "find_netconvert", lambda: fake)
    root = tmp_path / "cache"
    monkeypatch.setenv("CROSSROADS_CACHE_DIR", str(root))
    with pytest.raises(NetworkBuildError, match="something SUMO did not like"):
        build_network(load_spec("b_two_lane"))
    assert list(root.iterdir()) == []


def test_a_build_finished_meanwhile_by_another_process_is_kept(tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """Two workers building the same net at once: the later one must not pull the earlier one's
    finished build from under a simulation already reading it (a batch lost an episode to
    FileNotFoundError so)."""
    spec = load_spec("a_single_lane")
    entry = tmp_path / "entry"
    real_build_into = build_mod._build_into

    def build_while_another_finishes(spec_, tmp, key):
        monkeypatch.setattr(build_mod, "_build_into", real_build_into)
        build_network(spec_, entry)  # the other worker, done first
        (entry / "in-use.marker").write_text("a simulation reads this build")
        real_build_into(spec_, tmp, key)

    monkeypatch.setattr(build_mod, "_build_into", build_while_another_finishes)
    net = build_network(spec, entry)
    assert net == entry / "net.net.xml" and net.is_file()
    assert (entry / "in-use.marker").is_file()  # theirs kept, not replaced
    assert [p.name for p in tmp_path.iterdir()] == ["entry"]  # ours cleaned up


def test_explicit_out_dir(tmp_path: Path) -> None:
    spec = load_spec("a_single_lane")
    net = build_network(spec, tmp_path / "mine")
    assert net == tmp_path / "mine" / "net.net.xml" and net.is_file()
    (tmp_path / "foreign").mkdir()
    (tmp_path / "foreign" / "keep.txt").write_text("not a build")
    with pytest.raises(NetworkBuildError, match="not a Crossroads network build"):
        build_network(spec, tmp_path / "foreign")



def test_a_connection_the_bezier_cannot_join_keeps_netconverts_lane(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A user's geometry where the paper's construction fails for a connection (PlanningError) still
    builds: that connection keeps netconvert's internal lane, and the build log says which."""
    real = build_mod.build_candidate

    def refuse_lefts_from_south(cid, task, approach_id, entrance, exit_, **kw):
        if entrance.id.startswith("south_in") and exit_.id.startswith("west_out"):
            raise build_mod.PlanningError("no Bezier here (test)")
        return real(cid, task, approach_id, entrance, exit_, **kw)

    monkeypatch.setattr(build_mod, "build_candidate", refuse_lefts_from_south)
    net = build_network(load_spec("b_two_lane"), tmp_path / "b")
    shaped = {(c.get("from"), c.get("to")) for c in ET.parse(tmp_path / "b" / "shapes.con.xml").getroot()}
    assert ("south_in", "west_out") not in shaped and ("south_in", "north_out") in shaped
    assert "kept netconvert's internal lane for south_in_" in (tmp_path / "b" / "netconvert.log").read_text()
    assert net.is_file()

def test_oblique_straight_agrees_with_sumo(tmp_path: Path) -> None:
    """A leg 30° off straight ahead is 'straight' for the spec and for SUMO (< 44°); the build
    checks SUMO's ``dir`` of every link against the spec and would fail otherwise."""
    spec = IntersectionSpec.model_validate({
        "name": "skew",
        "approaches": [
            {"name": "south", "bearing_deg": 180, "exit_lanes": 1, "entrance_lanes": [{"turns": ["straight"]}]},
            {"name": "north", "bearing_deg": 30, "exit_lanes": 1, "entrance_lanes": [{"turns": ["straight"]}]},
            {"name": "west", "bearing_deg": 270, "exit_lanes": 1, "entrance_lanes": [{"turns": ["right", "left"]}]},
        ],
    })
    # 30° off straight: both we and SUMO (< 44°) call it straight, so this builds.
    net = build_network(spec, tmp_path / "skew")
    assert net.is_file()


@pytest.mark.parametrize("name", SIX)
def test_internal_lanes_follow_the_candidate_paths(nets: dict[str, Path], name: str) -> None:
    """Every car connection's internal lanes (both parts where SUMO splits a turn at an internal
    junction) run along the paper's candidate path between its lanes: SUMO's traffic turns where
    the ego does, and its junction model sees the ego where it is."""
    root = ET.parse(nets[name]).getroot()
    shapes = {lane.get("id"): _points(lane.get("shape", "")) for lane in root.iter("lane")}
    via_next = {(c.get("from"), c.get("fromLane")): c.get("via") for c in root.iter("connection")
                if c.get("from", "").startswith(":") and c.get("via")}
    junction = read_junction(nets[name])
    checked = 0
    for c in root.iter("connection"):
        frm, to, via = c.get("from", ""), c.get("to", ""), c.get("via")
        entrance, exit_ = f"{frm}_{c.get('fromLane')}", f"{to}_{c.get('toLane')}"
        if frm.startswith(":") or not via or entrance not in junction.lanes or exit_ not in junction.lanes:
            continue  # internal links, crossings and walking areas, bike lanes
        chain = [via]
        while (nxt := via_next.get(tuple(chain[-1].rsplit("_", 1)))) is not None:
            chain.append(nxt)
        sumo = LineString(np.vstack([shapes[lane] for lane in chain]))
        path = build_candidate("c", "", frm, junction.lanes[entrance], junction.lanes[exit_])
        curve = path.points[(path.s >= path.s_stop_line) & (path.s <= path.s_exit)]
        assert max(sumo.distance(Point(p)) for p in curve) < 0.05, (entrance, exit_, chain)
        checked += 1
    assert checked >= 8


def _points(shape: str) -> np.ndarray:
    return np.array([[float(v) for v in xy.split(",")[:2]] for xy in shape.split()])


def test_a_kerb_radius_rounds_the_corners_and_moves_the_stop_lines_back(tmp_path: Path) -> None:
    """netconvert's node radius: the larger, the further from the centre the lanes end (and the
    gentler the turns between them)."""
    data = load_spec("a_single_lane").model_dump()
    stops = {}
    for radius in (4.0, 9.0):
        spec = IntersectionSpec.model_validate({**data, "name": f"kerb-{radius:g}", "kerb_radius_m": radius})
        node = next(n for n in build_mod._nodes_xml(spec).iter("node") if n.get("id") == "C")
        assert node.get("radius") == f"{radius:.3f}"
        junction = read_junction(build_mod.build_network(spec, tmp_path / f"r{radius:g}"))
        stops[radius] = float(np.hypot(*junction.default_approach().stop_line.mean(axis=0)))
    assert stops[9.0] > stops[4.0] + 2.0
