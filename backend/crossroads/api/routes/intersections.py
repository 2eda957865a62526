"""Intersections: the catalogue, the geometry of one (for drawing) and its candidate paths.

``{name}`` is a catalogue name and nothing else: it is never resolved as a file (the server's
working directory is nobody's business); uploaded networks have their own routes
(``/intersections/uploads/{id}``, :mod:`crossroads.api.routes.uploads`).

A network may hold several signalised junctions (a city net, a corridor): the geometry lists them
(``junctions``, for the studio's junction picker) and every route takes ``?junction=`` to read
another than the default (the traffic light nearest the net's centre). The geometry also says, per
approach, which tasks have a candidate path (``tasks``): the studio offers only those.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path as FilePath
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, HTTPException, Path, Query, Response

from crossroads.api.params import Page, paging
from crossroads.scenario.network_checks import program_json
from crossroads.constants import RHO_BEZIER
from crossroads.intersections import catalogue
from crossroads.network.export import junction_geometry
from crossroads.geometry import FloatArray
from crossroads.network.junction import JunctionError, read_junction
from crossroads.network.road import Junction
from crossroads.network.netxml import TRAFFIC_LIGHT_TYPES, read_net_xml
from crossroads.intersections.resolve import open_junction
from crossroads.planning import CandidatePath, PlanningError, plan_candidates
from crossroads.planning.internal_lanes import internal_lane_offsets, offset_warning, path_offset, worst_offset

router = APIRouter(prefix="/intersections", tags=["intersections"])

CatalogueName = Annotated[str, Path(min_length=1, max_length=100, description="a catalogue name (GET /intersections)")]
JunctionId = Annotated[str | None, Query(min_length=1, max_length=200, description=(
    "id of the signalised junction to read (one of the geometry's `junctions`); default: the "
    "traffic light nearest the network's centre"))]

TASKS = ("left", "straight", "right")
MAX_LISTED_JUNCTIONS = 50  # traffic-light nodes read for the picker, nearest the default first


def junction_of(ref: str | FilePath, junction: str | None, label: str) -> Junction:
    """The junction ``junction`` (None: the default) of the network ``ref``; a 422 naming the
    ``junction`` parameter when the network has no such signalised junction, or cannot read it.
    ``label`` stands for the network's file in the message (the server's paths are its own)."""
    try:
        return open_junction(ref, junction)
    except JunctionError as exc:
        if junction is None:
            raise
        raise HTTPException(status_code=422, detail=[{
            "loc": ["query", "junction"], "type": "value_error",
            "msg": _without_path(str(exc), label)}]) from None


def _without_path(message: str, label: str) -> str:
    """A reader's message with the network's path (its first words, up to ": ") as ``label``."""
    head, sep, rest = message.partition(": ")
    return f"{label}: {rest}" if sep and head.endswith((".xml", ".gz")) else message


def catalogue_junction(name: str, junction: str | None = None) -> Junction:
    """The junction of a catalogued intersection; 404 for any other name."""
    known = catalogue.list_intersections()
    if name not in known:
        raise HTTPException(status_code=404, detail=f"no intersection {name[:100]!r} in the catalogue "
                            f"({', '.join(known)}); uploaded networks are under /api/intersections/uploads")
    return junction_of(name, junction, name)


@router.get("")
def list_intersections(response: Response,
                       page: Annotated[Page, Depends(paging(100, 1000))]) -> list[dict[str, Any]]:
    """The catalogue: every intersection spec shipped under scenarios/intersections/."""
    items = []
    for name in page.slice(catalogue.list_intersections(), response):
        spec = catalogue.load_spec(name)
        items.append({
            "name": name,
            "description": spec.description,
            "legs": [leg.name for leg in spec.approaches],
        })
    return items


@router.get("/{name}")
def intersection_geometry(name: CatalogueName, junction: JunctionId = None) -> dict[str, Any]:
    """Lanes, junction polygon, medians, crossings, sidewalks and stop lines of one intersection,
    its signal program (what ``lights.phase`` indexes), which link of it each movement has, the
    tasks each approach has a path for, and the network's signalised junctions."""
    return {"name": name, **geometry_with_program(catalogue_junction(name, junction), name)}


def signal_links(junction: Junction) -> dict[str, list[dict[str, Any]]]:
    """Per approach, each signalised movement (entrance lane, turn) and its index into the
    program's state strings: what tells the editor the ego's light in each phase."""
    return {a.id: [{"lane": c.from_lane, "turn": c.turn, "link": c.tl_link_index}
                   for c in a.connections if c.tl_link_index is not None]
            for a in junction.approaches}


def geometry_with_program(junction: Junction, label: str) -> dict[str, Any]:
    """The geometry, the signal program and the signal links of a junction, the tasks of each
    approach and the network's junctions (``label``: the network's name in their messages)."""
    return {**junction_geometry(junction), "program": program_json(junction.net_file, junction.tl_id),
            "signal_links": signal_links(junction), **choices_of(junction, label)}


def choices_of(junction: Junction, label: str) -> dict[str, Any]:
    """What the studio's form may choose on this network: per approach the tasks with a candidate
    path (``tasks``), and the signalised junctions (``junctions``, up to
    :data:`MAX_LISTED_JUNCTIONS` nearest the default; ``junctions_not_listed`` counts the rest)."""
    net = junction.net_file.resolve()
    mtime = net.stat().st_mtime_ns
    listed, not_listed = _junctions_cached(net, mtime, label)
    return {"tasks": _tasks_cached(net, mtime, junction.id), "junctions": list(listed),
            "junctions_not_listed": not_listed}


@lru_cache(maxsize=64)
def _tasks_cached(net_file: FilePath, mtime_ns: int, junction_id: str) -> dict[str, list[str]]:
    """Per approach of the junction, the tasks ``plan_candidates`` finds a path for (the
    default ρ, as the preview draws them): the same planner a run and the save's checks use."""
    junction = open_junction(net_file, junction_id)
    tasks: dict[str, list[str]] = {}
    for approach in junction.approaches:
        tasks[approach.id] = []
        for task in TASKS:
            try:
                plan_candidates(junction, task, approach=approach)
            except PlanningError:
                continue
            tasks[approach.id].append(task)
    return tasks


@lru_cache(maxsize=16)
def _junctions_cached(net_file: FilePath, mtime_ns: int, label: str) -> tuple[tuple[dict[str, Any], ...], int]:
    """The network's signalised junctions, the default first then nearest it: ``id``, ``tl_id``,
    ``center``, ``approaches`` (how many), ``default``; one the reader cannot use has
    ``readable`` false and the ``reason``. Nodes joined into one junction are listed once."""
    net = read_net_xml(net_file)
    default = open_junction(net_file)
    cx, cy = default.center
    nodes = sorted((n for n, rec in net.nodes.items() if rec.type in TRAFFIC_LIGHT_TYPES),
                   key=lambda n: (n not in default.node_ids, (net.nodes[n].x - cx) ** 2 + (net.nodes[n].y - cy) ** 2, n))
    listed: list[dict[str, Any]] = []
    seen: set[str] = set()
    for node in nodes[:MAX_LISTED_JUNCTIONS]:
        if node in seen:
            continue
        try:
            junction = default if node in default.node_ids else read_junction(net_file, node)
        except JunctionError as exc:
            seen.add(node)
            listed.append({"id": node, "tl_id": None, "center": [round(net.nodes[node].x, 2), round(net.nodes[node].y, 2)],
                           "approaches": 0, "default": False, "readable": False,
                           "reason": _without_path(str(exc), label)})
            continue
        seen.update(junction.node_ids)
        listed.append({"id": junction.id, "tl_id": junction.tl_id,
                       "center": [round(float(v), 2) for v in junction.center],
                       "approaches": len(junction.approaches), "default": junction is default,
                       "readable": True, "reason": None})
    return tuple(listed), max(0, len(nodes) - MAX_LISTED_JUNCTIONS)


def paths_of(junction: Junction, task: str, approach: str | None, rho: float | None) -> list[dict[str, Any]]:
    """The candidate paths of ``task`` from ``approach`` (default: the south); 422 naming the
    parameter when there are none."""
    try:
        chosen = junction.approach(approach) if approach else junction.default_approach()
    except KeyError as exc:
        raise HTTPException(status_code=422, detail=f"approach: {exc.args[0]}") from exc
    try:
        candidates = plan_candidates(junction, task, approach=chosen, rho=rho)
    except PlanningError as exc:
        raise HTTPException(status_code=422, detail=f"task: {exc}") from exc
    lanes = {(c.from_lane, c.to_lane): c.via_shape for c in chosen.connections}
    return [{**c.to_json(), **_sumo_lane(c, lanes.get((c.entrance_lane, c.exit_lane)))} for c in candidates]


def _sumo_lane(path: CandidatePath, internal_lane: FloatArray | None) -> dict[str, Any]:
    """SUMO's internal lane of a candidate's movement, for drawing beside it, and how far apart
    the two run (``planning.internal_lanes``)."""
    if internal_lane is None:
        return {"sumo_internal_lane": None, "sumo_offset_m": None}
    max_m, _ = path_offset(path, internal_lane)
    return {"sumo_internal_lane": internal_lane.round(3).tolist(), "sumo_offset_m": round(max_m, 3)}


def internal_lanes_of(junction: Junction, name: str) -> dict[str, Any]:
    """How far SUMO's internal lanes run from the candidate paths: the farthest, the warning
    sentence (None when every movement is within half the ego's width) and every movement."""
    offsets = internal_lane_offsets(junction)
    worst = worst_offset(offsets)
    return {"max_m": None if worst is None or worst.max_m is None else round(worst.max_m, 3),
            "warning": offset_warning(offsets, name), "movements": [o.to_json() for o in offsets]}


@router.get("/{name}/internal-lanes")
def internal_lanes(name: CatalogueName, junction: JunctionId = None) -> dict[str, Any]:
    """How far SUMO's internal lanes run from the candidate paths of the same movements (the
    catalogue's builds draw them along the paths; see ``crossroads net check``)."""
    return internal_lanes_of(catalogue_junction(name, junction), name)


@router.get("/{name}/paths")
def candidate_paths(
    name: CatalogueName,
    task: Literal["left", "straight", "right"],
    junction: JunctionId = None,
    approach: Annotated[str | None, Query(max_length=200, description="incoming edge id; default: from the south")] = None,
    rho: Annotated[float | None, Query(gt=0.0, lt=1.0, description=(
        f"ρ of the Bezier construction for every path (the paper: {RHO_BEZIER}); default: chosen "
        "per path within the ego's steering limit"))] = None,
) -> list[dict[str, Any]]:
    """The candidate paths of a task: one per reachable target lane (SPEC §1)."""
    return paths_of(catalogue_junction(name, junction), task, approach, rho)
