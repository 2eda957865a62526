"""Reading SUMO networks into Junctions: real nets, SUMO's examples, and nets built here.

The real nets live in ``../shared/realnets`` (never copied into the repo); SUMO's examples come
from the installed ``sumo`` wheel; the rest are built with netconvert from plain XML in a tmp dir.
"""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import LineString, Point

from crossroads.network.junction import JunctionError, read_junction
from crossroads.network.road import Junction

REPO = Path(__file__).resolve().parents[2]
REALNETS = REPO.parent / "shared" / "realnets"
COLOGNE = REALNETS / "resco_cologne1" / "cologne1.net.xml"
TWO_WAY = REALNETS / "sumo-rl_2way-single-intersection" / "single-intersection.net.xml"


def _sumo_tools() -> Path | None:
    try:
        import sumo
    except ImportError:
        return None
    return Path(sumo.SUMO_HOME) / "tools"


TOOLS = _sumo_tools()
SCENARIOS = TOOLS / "sumolib" / "scenario" / "scenarios" if TOOLS else None
SUMO_EXAMPLES = {
    "cross": TOOLS / "game" / "cross" / "cross.net.xml" if TOOLS else None,
    "rilsa1": SCENARIOS / "RiLSA1" / "rilsa1.net.xml" if SCENARIOS else None,
    "rilsa1_both_tls": SCENARIOS / "RiLSA1BothTLS" / "rilsa1both.net.xml" if SCENARIOS else None,
    "rilsa_example1": SCENARIOS / "RealWorld" / "RiLSA_example1" / "rilsa1.net.xml"
    if SCENARIOS else None,
    "rilsa_example2": SCENARIOS / "RealWorld" / "RiLSA_example2" / "rilsa2.net.xml"
    if SCENARIOS else None,
    "rilsa_example3": SCENARIOS / "RealWorld" / "RiLSA_example3" / "rilsa3.net.xml"
    if SCENARIOS else None,
    "rilsa_example4": SCENARIOS / "RealWorld" / "RiLSA_example4" / "rilsa4.net.xml"
    if SCENARIOS else None,
}


def _need(path: Path | None) -> Path:
    if path is None or not path.is_file():
        pytest.skip(f"test network not available: {path}")
    return path


def _deg(rad: float) -> float:
    return math.degrees(rad) % 360.0


def _angle_diff_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


# --- building nets with netconvert ------------------------------------------------------------


def _netconvert_binary() -> str | None:
    beside_python = Path(sys.executable).parent / "netconvert"
    if beside_python.is_file():
        return str(beside_python)
    return shutil.which("netconvert")


NETCONVERT = _netconvert_binary()


def _write_xml(path: Path, root_tag: str, child_tag: str, rows: list[dict[str, object]]) -> None:
    root = ET.Element(root_tag)
    for row in rows:
        ET.SubElement(root, child_tag, {k: str(v) for k, v in row.items()})
    ET.ElementTree(root).write(path)


def _star(centre_type: str, legs: dict[str, float], lanes_in: int = 2, lanes_out: int = 2,
          length_m: float = 100.0, **edge_attrs: object) -> tuple[list[dict], list[dict]]:
    """Nodes and edges of a junction C with a two-way leg at each angle [deg, CCW from east]."""
    nodes: list[dict] = [{"id": "C", "x": 0, "y": 0, "type": centre_type}]
    edges: list[dict] = []
    for name, angle in legs.items():
        x, y = length_m * math.cos(math.radians(angle)), length_m * math.sin(math.radians(angle))
        nodes.append({"id": name, "x": round(x, 2), "y": round(y, 2)})
        edges.append({"id": f"{name}C", "from": name, "to": "C", "numLanes": lanes_in,
                      "speed": 13.89, **edge_attrs})
        edges.append({"id": f"C{name}", "from": "C", "to": name, "numLanes": lanes_out,
                      "speed": 13.89, **edge_attrs})
    return nodes, edges


def _build(directory: Path, name: str, nodes: list[dict], edges: list[dict],
           *options: str) -> Path:
    if NETCONVERT is None:
        pytest.skip("netconvert is not installed")
    nod, edg, net = (directory / f"{name}.nod.xml", directory / f"{name}.edg.xml",
                     directory / f"{name}.net.xml")
    _write_xml(nod, "nodes", "node", nodes)
    _write_xml(edg, "edges", "edge", edges)
    subprocess.run([NETCONVERT, "-n", str(nod), "-e", str(edg), "--no-turnarounds", *options,
                    "-o", str(net)], check=True, capture_output=True, timeout=60)
    return net


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Every netconvert-built test net, by name (built once per module, ~0.3 s each)."""
    d = tmp_path_factory.mktemp("nets")
    nets = {}
    nets["tee"] = _build(d, "tee", *_star("traffic_light", {"E": 0, "S": 270, "W": 180}))
    nets["five_skewed"] = _build(
        d, "five_skewed", *_star("traffic_light", {"A": 10, "B": 85, "C2": 150, "D": 215, "F": 290},
                                 lanes_in=2, lanes_out=1))
    nets["walk"] = _build(d, "walk", *_star("traffic_light", {"E": 0, "N": 90, "W": 180, "S": 270},
                                             sidewalkWidth=2.0, bikeLaneWidth=1.5),
                          "--crossings.guess")
    nets["lefthand"] = _build(d, "lefthand", *_star("traffic_light", {"E": 0, "N": 90, "W": 180,
                                                                     "S": 270}), "--lefthand")
    # a divided north leg: the two carriageways' centre lines 12 m apart (a green belt)
    nodes, edges = _star("traffic_light", {"E": 0, "N": 90, "W": 180, "S": 270})
    for e in edges:
        if e["id"] == "NC":
            e["shape"] = "-6,100 -6,8 0,0"
        elif e["id"] == "CN":
            e["shape"] = "0,0 6,8 6,100"
    nets["divided"] = _build(d, "divided", nodes, edges)
    nets["priority"] = _build(d, "priority", *_star("priority", {"E": 0, "N": 90, "W": 180,
                                                                 "S": 270}))
    nets["two_legs"] = _build(d, "two_legs", *_star("traffic_light", {"E": 0, "W": 180}))
    # two signalized nodes 12 m apart: one intersection when their lights are joined, an
    # unsupported split intersection when each keeps its own program
    pair_nodes = [{"id": "A", "x": 0, "y": 0, "type": "traffic_light"},
                  {"id": "B", "x": 12, "y": 0, "type": "traffic_light"},
                  {"id": "W", "x": -100, "y": 0}, {"id": "E", "x": 112, "y": 0},
                  {"id": "S", "x": 0, "y": -100}, {"id": "N", "x": 12, "y": 100}]
    pair_edges = [{"id": f"{a}{b}", "from": a, "to": b, "numLanes": 2}
                  for a, b in [("W", "A"), ("A", "W"), ("A", "B"), ("B", "A"), ("E", "B"),
                               ("B", "E"), ("S", "A"), ("A", "S"), ("N", "B"), ("B", "N")]]
    nets["joined"] = _build(d, "joined", pair_nodes, pair_edges, "--tls.join")
    nets["split"] = _build(d, "split", pair_nodes, pair_edges)
    return nets


# --- invariants every readable net satisfies --------------------------------------------------

READABLE = ["cologne", "two_way", *SUMO_EXAMPLES, "tee", "five_skewed", "walk", "joined",
            "lefthand", "divided"]


@pytest.fixture(scope="module")
def junctions(built: dict[str, Path]) -> dict[str, Junction]:
    """Every readable test net's Junction, by name, read once on first use."""

    class _Lazy(dict):  # lazily, so a missing net only skips the tests that use it
        def __missing__(self, key: str) -> Junction:
            if key == "cologne":
                path = _need(COLOGNE)
            elif key == "two_way":
                path = _need(TWO_WAY)
            elif key in SUMO_EXAMPLES:
                path = _need(SUMO_EXAMPLES[key])
            else:
                path = built[key]
            self[key] = read_junction(path)
            return self[key]

    return _Lazy()


@pytest.mark.parametrize("name", READABLE)
def test_every_entrance_lane_has_turns_and_known_targets(junctions, name):
    j = junctions[name]
    assert len(j.approaches) >= 3
    for a in j.approaches:
        assert a.entrance_lanes, a.id
        for lane in a.entrance_lanes:
            assert lane.allows_cars
            assert a.turns_of(lane.id), f"{name}: {lane.id} has no turn"
        for c in a.connections:
            assert c.to_lane in j.lanes
            assert c.from_lane in {l.id for l in a.entrance_lanes}
        # entrance lanes are ordered kerb side first
        assert [l.index for l in a.entrance_lanes] == sorted(l.index for l in a.entrance_lanes)


@pytest.mark.parametrize("name", READABLE)
def test_stop_line_spans_the_lane_ends(junctions, name):
    j = junctions[name]
    for a in j.approaches:
        line = LineString(a.stop_line)
        forward = np.array([math.cos(a.heading_rad), math.sin(a.heading_rad)])
        for lane in a.entrance_lanes:
            # every lane ends on the line or, where SUMO staggers the ends of a bent edge, just
            # past it: the line sits at the most upstream end
            past = float(np.dot(lane.end - a.stop_line[0], forward))
            assert -1e-6 < past < (2.5 if name == "divided" else 0.5), (name, lane.id)
            assert line.distance(Point(lane.end)) <= past + 1e-6, (name, lane.id)
        # perpendicular to the heading, and at least as long as the lanes are wide together
        direction = a.stop_line[1] - a.stop_line[0]
        assert abs(np.dot(direction, [math.cos(a.heading_rad), math.sin(a.heading_rad)])) < 1e-6
        # (SUMO rounds coordinates to 1 cm, so lane spacings can be a few cm off their widths)
        assert line.length >= sum(l.width_m for l in a.entrance_lanes) - 0.05
        # it runs from right to left: the left normal of the heading points along it
        left = np.array([-math.sin(a.heading_rad), math.cos(a.heading_rad)])
        assert np.dot(direction, left) > 0


@pytest.mark.parametrize("name", READABLE)
def test_exit_lanes_are_paired_and_opposite(junctions, name):
    j = junctions[name]
    outgoing = [a.outgoing_edge for a in j.approaches if a.outgoing_edge is not None]
    assert len(outgoing) == len(set(outgoing)), "an exit edge serves two legs"
    for a in j.approaches:
        if a.outgoing_edge is None:
            continue
        assert a.outgoing_edge in j.exit_edges
        assert a.exit_lanes
        for lane in a.exit_lanes:
            assert lane.edge_id == a.outgoing_edge
            assert _angle_diff_deg(_deg(lane.start_heading), _deg(a.heading_rad) + 180.0) < 45.0
            # the exit starts near where the entrance ends
            assert np.hypot(*(lane.start - a.entrance_lanes[-1].end)) < 40.0


@pytest.mark.parametrize("name", READABLE)
def test_drivable_area_covers_lane_ends(junctions, name):
    j = junctions[name]
    area = j.drivable_area.buffer(1e-6)
    for a in j.approaches:
        for lane in a.entrance_lanes:
            assert area.covers(Point(lane.end)), (name, lane.id)
        for c in a.connections:
            assert area.covers(Point(j.lanes[c.to_lane].start)), (name, c.to_lane)
            if c.via_shape is not None:
                assert area.buffer(0.5).covers(LineString(c.via_shape)), (name, c.via_lane)
    assert j.polygon.is_valid and j.polygon.area > 10.0
    assert j.drivable_area.covers(Point(j.center)) or j.polygon.distance(Point(j.center)) < 5.0


@pytest.mark.parametrize("name", READABLE)
def test_default_approach_points_north(junctions, name):
    heading = junctions[name].default_approach().heading_rad
    assert _angle_diff_deg(_deg(heading), 90.0) < 30.0


# --- the real nets ----------------------------------------------------------------------------


def test_cologne_legs_medians_and_traffic_light(junctions):
    j = junctions["cologne"]
    assert j.id == "cluster_357187_359543"
    assert j.tl_id == "GS_cluster_357187_359543"  # differs from the junction id
    assert j.node_ids == ("cluster_357187_359543",)
    # the legs point (CCW from east) at 13/109/193/291°; traffic drives in opposite to them
    headings = sorted(_deg(a.heading_rad) for a in j.approaches)
    expected = sorted((leg + 180.0) % 360.0 for leg in (13.0, 109.0, 193.0, 291.0))
    assert len(headings) == 4
    for h, e in zip(headings, expected):
        assert _angle_diff_deg(h, e) < 10.0
    for a in j.approaches:
        assert len(a.entrance_lanes) == 2 and len(a.exit_lanes) == 2
        assert {t for l in a.entrance_lanes for t in a.turns_of(l.id)} >= {"left", "straight",
                                                                           "right"}
        assert all(c.tl_link_index is not None for c in a.connections)
    with_median = {a.id for a in j.approaches if a.median is not None}
    assert with_median == {"27115123#3", "23429231#1"}  # the two arms of the primary road
    for a in j.approaches:
        if a.median is not None:
            inner, outer = a.entrance_lanes[-1], a.exit_lanes[-1]
            gap = np.hypot(*(inner.end - outer.start)) - (inner.width_m + outer.width_m) / 2
            assert 8.0 < gap < 13.0
            assert a.median.area > 8.0 * 60.0  # ≥ 8 m wide over most of 80 m
            assert not a.median.intersects(inner.polygon().buffer(-0.05))
    assert j.crossings == () and j.walking_areas == ()


def test_two_way_single_intersection_old_format(junctions):
    j = junctions["two_way"]
    assert (j.id, j.tl_id) == ("t", "t")
    assert len(j.approaches) == 4
    for a in j.approaches:
        assert len(a.entrance_lanes) == 2
        assert a.median is None
        assert a.turns_of(a.entrance_lanes[0].id) == {"right", "straight"}
        assert a.turns_of(a.entrance_lanes[1].id) == {"left"}
    assert sorted(round(_deg(a.heading_rad)) % 360 for a in j.approaches) == [0, 90, 180, 270]
    assert j.default_approach().id == "s_t"


def test_sumo_example_with_crossings(junctions):
    j = junctions["rilsa1"]
    assert len(j.crossings) == 4 and len(j.walking_areas) == 4
    assert {c.tl_link_index for c in j.crossings} == {12, 13, 14, 15}
    assert {frozenset(c.crossed_edges) for c in j.crossings} == {
        frozenset(p) for p in (("mn", "nm"), ("me", "em"), ("ms", "sm"), ("mw", "wm"))}
    # the sidewalks are lane 0 of every leg, not entrance lanes
    assert len(j.sidewalks) == 8
    for a in j.approaches:
        assert [l.index for l in a.entrance_lanes] == [1, 2]


def test_two_signalized_nodes_sharing_one_light(junctions):
    """RiLSA example 2: a divided main road meets a side road; SUMO models it as two nodes."""
    j = junctions["rilsa_example2"]
    assert set(j.node_ids) == {"0n", "0s"} and j.tl_id == "0"
    assert {a.id for a in j.approaches} == {"em", "wm", "sm"}
    em = j.approach("em")
    # the left turn from the main road crosses the median between the two nodes
    lefts = em.connections_for("left")
    assert [c.to_lane for c in lefts] == ["ms_0"] and lefts[0].tl_link_index == 2
    assert em.median is not None and j.approach("wm").median is not None


# --- the built nets ---------------------------------------------------------------------------


def test_tee_junction(junctions):
    j = junctions["tee"]
    assert {a.id for a in j.approaches} == {"EC", "SC", "WC"}
    assert {t for l in j.approach("SC").entrance_lanes
            for t in j.approach("SC").turns_of(l.id)} == {"left", "right"}
    assert j.approach("SC").outgoing_edge == "CS"
    assert set(j.exit_edges) == {"CE", "CS", "CW"}


def test_five_skewed_legs(junctions):
    j = junctions["five_skewed"]
    assert len(j.approaches) == 5
    headings = sorted(_deg(a.heading_rad) for a in j.approaches)
    expected = sorted((leg + 180.0) % 360.0 for leg in (10, 85, 150, 215, 290))
    for h, e in zip(headings, expected):
        assert _angle_diff_deg(h, e) < 3.0
    for a in j.approaches:
        assert len(a.entrance_lanes) == 2 and len(a.exit_lanes) == 1
        assert a.outgoing_edge == "C" + a.id[:-1]  # leg X: XC in, CX out


def test_crossings_sidewalks_and_bike_lanes(junctions):
    j = junctions["walk"]
    assert len(j.crossings) == 4
    for c in j.crossings:
        assert c.tl_link_index is not None and c.width_m > 0 and c.polygon.area > 10.0
        assert len(c.crossed_edges) == 2
    assert len(j.walking_areas) == 4
    assert len(j.sidewalks) == 8 and all(l.allowed_classes == {"pedestrian"} for l in j.sidewalks)
    assert len(j.bike_lanes) == 8 and all(l.allowed_classes == {"bicycle"} for l in j.bike_lanes)
    for a in j.approaches:  # cars only: lanes 2 and 3, after the sidewalk and the bike lane
        assert [l.index for l in a.entrance_lanes] == [2, 3]
        assert [l.index for l in a.exit_lanes] == [2, 3]
    lanes = set(j.lanes)
    assert not lanes & {l.id for l in (*j.sidewalks, *j.bike_lanes)}


def test_divided_leg_has_a_median(junctions):
    j = junctions["divided"]
    medians = {a.id: a.median for a in j.approaches if a.median is not None}
    assert set(medians) == {"NC"}
    # lanes hug the edge centre lines at x = ±6 m, so the strip is 12 m wide over 80 m
    assert 11.0 * 80.0 < medians["NC"].area < 13.0 * 80.0
    assert medians["NC"].contains(Point(j.center[0], j.center[1] + 50.0))  # midway, 50 m north
    for lane in (*j.approach("NC").entrance_lanes, *j.approach("NC").exit_lanes):
        assert medians["NC"].intersection(lane.polygon()).area < 0.5


def test_lefthand_net(junctions):
    j = junctions["lefthand"]
    assert len(j.approaches) == 4
    for a in j.approaches:
        assert a.median is None and a.outgoing_edge == "C" + a.id[0]
        # lane 0 is the kerb lane, on the left in left-hand traffic: it turns left
        assert "left" in a.turns_of(a.entrance_lanes[0].id)


def test_joined_traffic_lights_form_one_junction(junctions):
    j = junctions["joined"]
    assert j.node_ids == ("A", "B") and j.tl_id.startswith("joined")
    assert {a.id for a in j.approaches} == {"WA", "EB", "SA", "NB"}
    assert "AB" not in j.exit_edges and "BA" not in j.exit_edges
    straight = {c.to_lane.rsplit("_", 1)[0] for c in j.approach("WA").connections_for("straight")}
    assert straight == {"BE"}  # traced through the inner edge A→B


def test_explicit_junction_id(junctions):
    assert read_junction(_need(COLOGNE), "cluster_357187_359543").id == "cluster_357187_359543"


# --- errors -----------------------------------------------------------------------------------


def test_missing_file(tmp_path):
    with pytest.raises(JunctionError, match="not found"):
        read_junction(tmp_path / "nope.net.xml")


def test_not_xml(tmp_path):
    bad = tmp_path / "bad.net.xml"
    bad.write_text("<net><edge id='a'></net>")
    with pytest.raises(JunctionError, match="not well-formed XML"):
        read_junction(bad)


def test_not_a_sumo_net(tmp_path):
    routes = tmp_path / "x.rou.xml"
    routes.write_text("<routes><vType id='car'/></routes>")
    with pytest.raises(JunctionError, match="not a SUMO network.*<routes>"):
        read_junction(routes)


def test_no_traffic_light_in_net(built):
    with pytest.raises(JunctionError, match="no traffic-light junction"):
        read_junction(built["priority"])


def test_junction_without_traffic_light(built):
    with pytest.raises(JunctionError, match=r"'C' has no traffic light \(its type is 'priority'\)"):
        read_junction(built["priority"], "C")


def test_unknown_junction_lists_known_ones(built):
    with pytest.raises(JunctionError, match=r"'Z' does not exist; traffic-light junctions: 'C'"):
        read_junction(built["tee"], "Z")


def test_fewer_than_three_approaches(built):
    with pytest.raises(JunctionError, match=r"2 approach\(es\) with car lanes.*at least 3"):
        read_junction(built["two_legs"])


def test_intersection_split_between_two_lights(built):
    with pytest.raises(JunctionError, match="controlled by another traffic light"):
        read_junction(built["split"])
