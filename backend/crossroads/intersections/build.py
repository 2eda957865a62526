"""Build an :class:`IntersectionSpec` into a SUMO network (``.net.xml``) with netconvert, cached.

What is written (SUMO "plain XML", https://sumo.dlr.de/docs/Networks/PlainXML.html):

* ``plain.nod.xml``: the junction ``C`` at the origin (a static traffic light, tl id ``C``) and one
  dead-end node at the far end of every leg.
* ``plain.edg.xml``: per leg ``<name>_in`` (towards C) and ``<name>_out``, with explicit shapes so
  that a median (green belt) shows as a gap between the two edges, sidewalks (``sidewalkWidth``)
  and bike lanes (``bikeLaneWidth``) added by SUMO to the right of the car lanes.
* ``plain.con.xml``: every connection explicitly (car lanes as planned by
  :meth:`IntersectionSpec.lane_links`, plus bicycle links), and the pedestrian crossings. No
  U-turns. Explicit connections keep the number of candidate paths under our control.
* ``program.tll.xml``: the static signal program of SPEC §2.

Link indices of a traffic light are assigned by netconvert, so the build has two passes:
pass 1 builds the net with SUMO's default program (twice: the second time with each crossing's
ends moved onto the kerb, :mod:`crossroads.intersections.crossing_ends`, from the first's geometry), we read the link index of every connection and
crossing, compute the state strings, and pass 2 (``netconvert -s pass1.net.xml --tllogic-files``)
replaces the program. The build then checks that SUMO's own turn classification (``dir``) agrees
with the spec's and that link indices did not move between the passes.

Pass 2 also gives every car connection the shape of the candidate path between its lanes
(``shapes.con.xml``: the cubic Bezier of :func:`crossroads.planning.routes.build_candidate` with
the ρ the planner chooses, drawn on pass 1's lanes), so SUMO's internal lanes run where the ego's
candidate paths run. Why: netconvert's own internal lanes were up to 2.5 m off the Bezier paths into the two inner
exit lanes of the nominal left turn (docs/tried/world.md), so SUMO's junction model
placed the ego, its followers and its foes where the ego was not.

Cache: a build lives in ``<cache root>/<key>/`` where the key hashes the canonical spec JSON,
:data:`BUILD_VERSION` and the SUMO version. The cache root is ``$CROSSROADS_CACHE_DIR`` or
``~/.cache/crossroads/nets`` (:func:`crossroads.settings.net_cache_dir`). Builds happen in a
temporary sibling directory renamed into place at the end, so a failed or interrupted build never
leaves a half-written entry.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Literal

import numpy as np

from crossroads.constants import ALL_RED_S, PEDESTRIAN_CLEARANCE_S

from crossroads.intersections.crossing_ends import Shape, kerbside_crossing_shapes
from crossroads.intersections.spec import ApproachSpec, IntersectionSpec
from crossroads.network.junction import read_junction
from crossroads.planning.drivable import road_check
from crossroads.planning.routes import PlanningError, build_candidate
from crossroads.settings import net_cache_dir

BUILD_VERSION = "5"  # bump whenever the written XML or the netconvert options change
JUNCTION_ID = "C"  # the junction's node id, also the traffic light's id
NET_FILE = "net.net.xml"
BUILD_INFO_FILE = "build.json"
LINKS_FILE = "tls_links.json"

# netconvert options shared by both passes.
_COMMON_OPTIONS = [
    "--offset.disable-normalization", "true",  # keep our frame: the junction centre at (0, 0)
    "--no-turnarounds", "true",
    "--walkingareas", "true",
    "--crossings.guess", "false",  # crossings are given explicitly, per leg
    "--sidewalks.guess", "false",
    "--bikelanes.guess", "false",
    "--junctions.corner-detail", "5",  # rounded kerbs
    "--lefthand", "false",  # right-hand traffic
]

# SUMO's connection "dir" codes accepted for each of our turns (L/R: SUMO's partial left/right).
_SUMO_DIRS = {"straight": {"s"}, "left": {"l", "L"}, "right": {"r", "R"}}


class NetworkBuildError(RuntimeError):
    """netconvert failed, or the network it built disagrees with the spec."""


@dataclass(frozen=True)
class TlsLink:
    """One controlled link of the junction's traffic light (a row of the state strings)."""

    link_index: int
    kind: str  # "vehicle" (cars and bicycles share lanes) | "bicycle" (bike-only) | "crossing"
    leg: str  # the entrance leg, or the crossed leg for a crossing
    turn: str | None  # left/straight/right; None for a crossing
    from_lane: str  # SUMO lane id (for crossings: the walking area's lane)
    to_lane: str  # SUMO lane id (for crossings: the crossing's lane)


# ---- public API -------------------------------------------------------------------------------
def build_network(spec: IntersectionSpec, out_dir: str | Path | None = None, *, force: bool = False) -> Path:
    """Build ``spec`` into a SUMO network and return the path of its ``.net.xml``.

    ``out_dir`` (default: the cache entry for the spec, see :func:`cache_key`) receives the net,
    the plain XML inputs, ``netconvert.log``, ``tls_links.json`` and ``build.json``. When it
    already holds a build of the same spec, netconvert is not run (unless ``force``). An existing
    ``out_dir`` that is not a Crossroads build is never overwritten.
    """
    key = cache_key(spec)
    entry = Path(out_dir) if out_dir is not None else net_cache_dir() / key
    if not force and _is_build_of(entry, key):
        return entry / NET_FILE
    if entry.exists() and not _is_build_dir(entry) and any(entry.iterdir()):
        raise NetworkBuildError(f"{entry} exists and is not a Crossroads network build; refusing to replace it")

    entry.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{entry.name}.", suffix=".tmp", dir=entry.parent))
    try:
        _build_into(spec, tmp, key)
        if not force and _is_build_of(entry, key):
            # Another process finished the same build meanwhile, and may be reading it already:
            # keep theirs (as good as ours) rather than pull it from under them.
            return entry / NET_FILE
        if entry.exists():
            shutil.rmtree(entry)
        try:
            os.replace(tmp, entry)
        except OSError:
            # Another process completed the same build meanwhile: theirs is as good as ours.
            if not _is_build_of(entry, key):
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return entry / NET_FILE


def cache_key(spec: IntersectionSpec) -> str:
    """sha256 of the canonical spec JSON, :data:`BUILD_VERSION` and the SUMO version."""
    canonical = json.dumps(spec.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
    payload = "\n".join([canonical, BUILD_VERSION, sumo_version()])
    return hashlib.sha256(payload.encode()).hexdigest()


@lru_cache(maxsize=1)
def sumo_version() -> str:
    """The installed SUMO version, from the package metadata (no process started) or netconvert."""
    for dist in ("eclipse-sumo", "sumolib"):
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            continue
    out = subprocess.run([str(find_netconvert()), "--version"], capture_output=True, text=True, check=False)
    return out.stdout.splitlines()[0] if out.stdout else "unknown"


def find_netconvert() -> Path:
    """netconvert beside the running Python (a venv with eclipse-sumo), on PATH, or in $SUMO_HOME/bin."""
    candidates = [Path(sys.executable).parent / "netconvert"]
    on_path = shutil.which("netconvert")
    if on_path:
        candidates.append(Path(on_path))
    if os.environ.get("SUMO_HOME"):
        candidates.append(Path(os.environ["SUMO_HOME"]) / "bin" / "netconvert")
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    raise NetworkBuildError("netconvert not found (looked beside Python, on PATH and in $SUMO_HOME/bin)")


def read_tls_links(net_dir: str | Path) -> list[TlsLink]:
    """The traffic light's links of a build directory (written by :func:`build_network`)."""
    data = json.loads((Path(net_dir) / LINKS_FILE).read_text())
    return [TlsLink(**row) for row in data]


# ---- the build --------------------------------------------------------------------------------
def _build_into(spec: IntersectionSpec, work: Path, key: str) -> None:
    """Write the plain XML into ``work``, run both netconvert passes and check the result."""
    plain = {
        "nod": work / "plain.nod.xml", "edg": work / "plain.edg.xml", "con": work / "plain.con.xml",
    }
    _write_xml(_nodes_xml(spec), plain["nod"])
    _write_xml(_edges_xml(spec), plain["edg"])
    _write_xml(_connections_xml(spec), plain["con"])
    log = work / "netconvert.log"

    first = work / "pass1.net.xml"
    pass1 = ["--node-files", plain["nod"], "--edge-files", plain["edg"], "--connection-files", plain["con"],
             "--output-file", first]
    _netconvert(pass1, log, spec.name)
    # again, with the crossings' ends on the kerb and off the car lanes to be (the connection
    # shapes below), where people wait (intersections/crossing_ends.py)
    planned, _ = _connection_shapes_xml(spec, first)
    crossing_shapes = kerbside_crossing_shapes(first, _car_paths(planned, first))
    _write_xml(_connections_xml(spec, crossing_shapes), plain["con"])
    _netconvert(pass1, log, spec.name)
    links = _tls_links(spec, first)
    _write_xml(_program_xml(spec, links), work / "program.tll.xml")
    shapes, unshaped = _connection_shapes_xml(spec, first)
    _write_xml(shapes, work / "shapes.con.xml")
    with log.open("a") as f:  # a user's geometry the Bezier cannot join keeps netconvert's lane
        f.writelines(f"kept netconvert's internal lane for {name}: {why}\n" for name, why in unshaped)

    final = work / NET_FILE
    _netconvert(["--sumo-net-file", first, "--tllogic-files", work / "program.tll.xml",
                 "--connection-files", work / "shapes.con.xml", "--output-file", final], log, spec.name)
    again = _tls_links(spec, final)
    if [(k.link_index, k.from_lane, k.to_lane) for k in again] != [(k.link_index, k.from_lane, k.to_lane) for k in links]:
        raise NetworkBuildError(f"{spec.name}: traffic-light link indices changed between the two netconvert passes")
    first.unlink()

    (work / LINKS_FILE).write_text(json.dumps([asdict(k) for k in links], indent=1))
    (work / "spec.json").write_text(spec.model_dump_json(indent=2))
    info = {"key": key, "name": spec.name, "build_version": BUILD_VERSION, "sumo_version": sumo_version(),
            "net_file": NET_FILE, "tl_id": JUNCTION_ID}
    # Written last: a directory with build.json is a complete build.
    (work / BUILD_INFO_FILE).write_text(json.dumps(info, indent=1))


def _car_paths(shapes: ET.Element, net_file: Path) -> list[tuple[np.ndarray, float]]:
    """(centre line, width) of every shaped connection of ``shapes``, its width its entrance lane's."""
    widths = {lane.get("id", ""): float(lane.get("width", "3.2")) for lane in ET.parse(net_file).getroot().iter("lane")}
    paths = []
    for c in shapes.iter("connection"):
        points = np.array([[float(v) for v in p.split(",")] for p in c.get("shape", "").split()])
        paths.append((points, widths.get(f"{c.get('from')}_{c.get('fromLane')}", 3.2)))
    return paths


def _netconvert(args: list[str | Path], log: Path, name: str) -> None:
    cmd = [str(find_netconvert()), *map(str, args), *_COMMON_OPTIONS]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    with log.open("a") as f:
        f.write(f"$ {' '.join(cmd)}\n{proc.stdout}{proc.stderr}\n")
    if proc.returncode != 0:
        raise NetworkBuildError(
            f"netconvert failed for intersection {name!r} (exit {proc.returncode}):\n{proc.stderr.strip()}"
        )


def _is_build_dir(path: Path) -> bool:
    return (path / BUILD_INFO_FILE).is_file()


def _is_build_of(path: Path, key: str) -> bool:
    try:
        info = json.loads((path / BUILD_INFO_FILE).read_text())
    except (OSError, ValueError):
        return False
    return info.get("key") == key and (path / NET_FILE).is_file()


def _write_xml(root: ET.Element, path: Path) -> None:
    ET.indent(root)
    ET.ElementTree(root).write(path, encoding="UTF-8", xml_declaration=True)


# ---- geometry and lanes -----------------------------------------------------------------------
def _leg_frame(a: ApproachSpec) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]]:
    """(origin, out, right) of a leg [m]: its centre line starts at ``origin`` and runs along the unit
    vector ``out``; ``right`` is the unit vector to the right of ``out`` (the exit edge's side)."""
    b = math.radians(a.bearing_deg)
    out = (math.sin(b), math.cos(b))  # compass bearing -> (east, north)
    right = (math.cos(b), -math.sin(b))
    origin = (a.lateral_offset_m * right[0], a.lateral_offset_m * right[1])
    return origin, out, right


def _edge_shape(a: ApproachSpec, incoming: bool) -> str:
    """Shape of an edge's reference line, from the centre (or its far end) in the driving direction.

    SUMO lays lanes to the right of an edge's shape (spreadType "right"), so shifting each
    direction's line by half the median away from the leg's centre line leaves a median-wide gap.
    """
    origin, out, right = _leg_frame(a)
    side = -0.5 * a.median_width_m if incoming else 0.5 * a.median_width_m
    pts = [
        (origin[0] + t * out[0] + side * right[0], origin[1] + t * out[1] + side * right[1])
        for t in (0.0, a.length_m)
    ]
    if incoming:
        pts.reverse()
    return " ".join(f"{x:.3f},{y:.3f}" for x, y in pts)


def _car_lane(a: ApproachSpec, car_index: int) -> int:
    """SUMO lane index of car lane ``car_index`` (0 = rightmost): sidewalk and bike lane come first."""
    return car_index + (a.sidewalk_width_m > 0) + (a.bike_lane_width_m > 0)


def _bike_lane(a: ApproachSpec) -> int | None:
    """SUMO lane index of the leg's bike lane, if it has one."""
    return int(a.sidewalk_width_m > 0) if a.bike_lane_width_m > 0 else None


def _nodes_xml(spec: IntersectionSpec) -> ET.Element:
    root = ET.Element("nodes")
    centre = {"id": JUNCTION_ID, "x": "0.00", "y": "0.00", "type": "traffic_light", "tlType": "static"}
    if spec.kerb_radius_m is not None:
        centre["radius"] = f"{spec.kerb_radius_m:.3f}"
    ET.SubElement(root, "node", centre)
    for a in spec.approaches:
        origin, out, _ = _leg_frame(a)
        x, y = origin[0] + a.length_m * out[0], origin[1] + a.length_m * out[1]
        ET.SubElement(root, "node", id=a.name, x=f"{x:.3f}", y=f"{y:.3f}", type="dead_end")
    return root


def _edges_xml(spec: IntersectionSpec) -> ET.Element:
    root = ET.Element("edges")
    for a in spec.approaches:
        for incoming in (True, False):
            attrs = {
                "id": a.in_edge if incoming else a.out_edge,
                "from": a.name if incoming else JUNCTION_ID,
                "to": JUNCTION_ID if incoming else a.name,
                "numLanes": str(len(a.entrance_lanes) if incoming else a.exit_lanes),
                "speed": f"{a.speed_limit_mps:.4f}",
                "width": f"{a.lane_width_m:.3f}",
                "shape": _edge_shape(a, incoming),
            }
            if a.sidewalk_width_m > 0:
                attrs["sidewalkWidth"] = f"{a.sidewalk_width_m:.3f}"
            if a.bike_lane_width_m > 0:
                attrs["bikeLaneWidth"] = f"{a.bike_lane_width_m:.3f}"
            ET.SubElement(root, "edge", attrs)
    return root


def _bike_links(spec: IntersectionSpec) -> list[tuple[str, int, str, int]]:
    """Bicycle-only links ``(from_edge, from_lane, to_edge, to_lane)`` (SUMO lane indices).

    A leg with a bike lane sends it to the target's bike lane, or to the target's rightmost car
    lane where bicycles share it. A leg without one already carries bicycles on its car links,
    except into a target with a bike lane (car lanes there forbid bicycles): then the rightmost car
    lane allowing the turn gets a link into that bike lane. Only bicycles can use these links.
    """
    links = []
    for a in spec.approaches:
        targets = spec.turn_targets(a.name)
        for turn in ("right", "straight", "left"):
            lanes = [j for j, lane in enumerate(a.entrance_lanes) if turn in lane.turns]
            if not lanes:
                continue
            b = spec.approach(targets[turn])
            src = _bike_lane(a)
            dst = _bike_lane(b)
            if src is None and dst is None:
                continue  # bicycles ride the car lanes and their car links
            from_lane = src if src is not None else _car_lane(a, lanes[0])
            to_lane = dst if dst is not None else _car_lane(b, 0)
            links.append((a.in_edge, from_lane, b.out_edge, to_lane))
    return links


def _connections_xml(spec: IntersectionSpec, crossing_shapes: dict[frozenset[str], Shape] | None = None) -> ET.Element:
    """The spec's lane links, bicycle links and crossings; a crossing whose crossed edges are in
    ``crossing_shapes`` gets that centre line as its ``shape``."""
    root = ET.Element("connections")
    for link in spec.lane_links():
        a, b = spec.approach(link.from_leg), spec.approach(link.to_leg)
        ET.SubElement(root, "connection", {
            "from": a.in_edge, "to": b.out_edge,
            "fromLane": str(_car_lane(a, link.from_lane)), "toLane": str(_car_lane(b, link.to_lane)),
        })
    for from_edge, from_lane, to_edge, to_lane in _bike_links(spec):
        ET.SubElement(root, "connection", {
            "from": from_edge, "to": to_edge, "fromLane": str(from_lane), "toLane": str(to_lane),
        })
    for a in spec.approaches:
        if a.crossing:
            attrs = {"node": JUNCTION_ID, "edges": f"{a.in_edge} {a.out_edge}", "priority": "true"}
            shape = (crossing_shapes or {}).get(frozenset((a.in_edge, a.out_edge)))
            if shape is not None:
                attrs["shape"] = " ".join(f"{x:.3f},{y:.3f}" for x, y in shape)
            ET.SubElement(root, "crossing", attrs)
    return root


# [m] spacing of the points of a connection's shape: SUMO interpolates linearly between them, and a
# sagitta under 1 cm on the tightest left turn of the catalogue (R ≈ 8 m) needs ≤ 0.8 m
CONNECTION_SHAPE_SPACING_M = 0.5


def _connection_shapes_xml(spec: IntersectionSpec, net_file: Path) -> tuple[ET.Element, list[tuple[str, str]]]:
    """Every car connection of the spec with ``shape``: the paper's candidate path from the end of
    its entrance lane to the start of its exit lane, on the lanes of ``net_file`` (pass 1). Also the
    connections left without one, ``(from lane → to lane, why)``: those the Bezier construction
    cannot join (:class:`PlanningError`), which keep netconvert's internal lane."""
    junction = read_junction(net_file, JUNCTION_ID)
    root = ET.Element("connections")
    unshaped: list[tuple[str, str]] = []
    for link in spec.lane_links():
        a, b = spec.approach(link.from_leg), spec.approach(link.to_leg)
        from_lane, to_lane = _car_lane(a, link.from_lane), _car_lane(b, link.to_lane)
        entrance, exit_ = f"{a.in_edge}_{from_lane}", f"{b.out_edge}_{to_lane}"
        try:
            path = build_candidate("shape", "", a.in_edge, junction.lanes[entrance], junction.lanes[exit_],
                                   spacing_m=CONNECTION_SHAPE_SPACING_M, road=road_check(junction, a.in_edge))
        except PlanningError as exc:
            unshaped.append((f"{entrance} -> {exit_}", str(exc)))
            continue
        curve = path.points[(path.s >= path.s_stop_line) & (path.s <= path.s_exit)]
        ET.SubElement(root, "connection", {
            "from": a.in_edge, "to": b.out_edge, "fromLane": str(from_lane), "toLane": str(to_lane),
            "shape": " ".join(f"{x:.3f},{y:.3f}" for x, y in curve.tolist()),
        })
    return root, unshaped


# ---- the signal program -----------------------------------------------------------------------
def _tls_links(spec: IntersectionSpec, net_file: Path) -> list[TlsLink]:
    """Every link of the junction's traffic light in ``net_file``, classified against the spec."""
    root = ET.parse(net_file).getroot()
    crossing_legs: dict[str, str] = {}
    lane_allow: dict[str, str] = {}
    for edge in root.iter("edge"):
        if edge.get("function") == "crossing":
            crossed = edge.get("crossingEdges", "").split()
            crossing_legs[edge.get("id", "")] = crossed[0].rsplit("_", 1)[0] if crossed else "?"
        for lane in edge.iter("lane"):
            lane_allow[lane.get("id", "")] = lane.get("allow", "")
    leg_of_in = {a.in_edge: a for a in spec.approaches}
    leg_of_out = {a.out_edge: a.name for a in spec.approaches}
    links: list[TlsLink] = []
    for c in root.iter("connection"):
        if c.get("tl") != JUNCTION_ID:
            continue
        index = int(c.get("linkIndex", "-1"))
        frm, to = c.get("from", ""), c.get("to", "")
        from_lane, to_lane = f"{frm}_{c.get('fromLane')}", f"{to}_{c.get('toLane')}"
        if to in crossing_legs or frm in crossing_legs:
            crossing = to if to in crossing_legs else frm
            links.append(TlsLink(index, "crossing", crossing_legs[crossing], None, from_lane, to_lane))
            continue
        if frm not in leg_of_in or to not in leg_of_out:
            raise NetworkBuildError(f"{spec.name}: unexpected traffic-light link {frm} -> {to}")
        a = leg_of_in[frm]
        turn = next((t for t, leg in spec.turn_targets(a.name).items() if leg == leg_of_out[to]), None)
        sumo_dir = c.get("dir", "")
        if turn is None or sumo_dir not in _SUMO_DIRS[turn]:
            raise NetworkBuildError(
                f"{spec.name}: SUMO classifies {frm} -> {to} as dir {sumo_dir!r} but the spec makes it "
                f"{turn!r}; adjust the legs' bearings"
            )
        kind = "bicycle" if "bicycle" == lane_allow.get(to_lane) or "bicycle" == lane_allow.get(from_lane) else "vehicle"
        links.append(TlsLink(index, kind, a.name, turn, from_lane, to_lane))
    links.sort(key=lambda k: k.link_index)
    if [k.link_index for k in links] != list(range(len(links))):
        raise NetworkBuildError(f"{spec.name}: traffic-light link indices are not 0..n-1")
    return links


Stage = Literal["green", "clearance", "yellow", "all_red"]


def link_state(link: TlsLink, green_legs: tuple[str, ...], stage: Stage) -> str:
    """SUMO state character of one link in one stage of a phase.

    SPEC §2: right turns are permanently green-with-yield ('g'); straight links 'G' and left links
    'g' (unprotected: they yield to the opposite straight) while their leg has green (its
    ``green`` and ``clearance`` stages), 'y' in its yellow, 'r' otherwise and in the all-red. A
    crossing over a leg has its walk ('G') while that leg has red (its traffic runs parallel to
    the pedestrians), except in the pedestrian clearance at the end of that green, the yellows
    and the all-reds.
    """
    if link.kind == "crossing":
        return "G" if (stage == "green" and link.leg not in green_legs) else "r"
    if link.turn == "right":
        return "g"
    if stage == "all_red" or link.leg not in green_legs:
        return "r"
    if stage == "yellow":
        return "y"
    return "G" if link.turn == "straight" else "g"


def phase_stages(green_s: float, yellow_s: float) -> list[tuple[Stage, float]]:
    """The stages of one phase and their durations [s]: the walk (green), the pedestrian
    clearance, the yellow and the all-red (constants: PEDESTRIAN_CLEARANCE_S, ALL_RED_S);
    a green no longer than the clearance has no walk."""
    clearance = min(PEDESTRIAN_CLEARANCE_S, green_s)
    stages: list[tuple[Stage, float]] = [("green", green_s - clearance), ("clearance", clearance),
                                         ("yellow", yellow_s), ("all_red", ALL_RED_S)]
    return [(stage, duration) for stage, duration in stages if duration > 0]


def _program_xml(spec: IntersectionSpec, links: list[TlsLink]) -> ET.Element:
    root = ET.Element("tlLogics")
    logic = ET.SubElement(root, "tlLogic", id=JUNCTION_ID, type="static", programID="0", offset="0")
    for phase in spec.signal_phases:
        for stage, duration in phase_stages(phase.green_s, phase.yellow_s):
            state = "".join(link_state(k, phase.green_legs, stage) for k in links)
            ET.SubElement(logic, "phase", duration=f"{duration:g}", state=state)
    return root
