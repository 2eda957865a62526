"""Intersections: the catalogue, the geometry of one (for drawing) and its candidate paths.

``{name}`` is a catalogue name and nothing else: it is never resolved as a file (the server's
working directory is nobody's business); uploaded networks have their own routes
(``/intersections/uploads/{id}``, :mod:`crossroads.api.routes.uploads`).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, HTTPException, Path, Query, Response

from crossroads.api.params import Page, paging
from crossroads.scenario.network_checks import program_json
from crossroads.constants import RHO_BEZIER
from crossroads.intersections import catalogue
from crossroads.network.export import junction_geometry
from crossroads.geometry import FloatArray
from crossroads.network.model import Junction
from crossroads.intersections.resolve import open_junction
from crossroads.planning import CandidatePath, PlanningError, plan_candidates
from crossroads.planning.internal_lanes import internal_lane_offsets, offset_warning, path_offset, worst_offset

router = APIRouter(prefix="/intersections", tags=["intersections"])

CatalogueName = Annotated[str, Path(min_length=1, max_length=100, description="a catalogue name (GET /intersections)")]


def catalogue_junction(name: str) -> Junction:
    """The junction of a catalogued intersection; 404 for any other name."""
    known = catalogue.list_intersections()
    if name not in known:
        raise HTTPException(status_code=404, detail=f"no intersection {name[:100]!r} in the catalogue "
                            f"({', '.join(known)}); uploaded networks are under /api/intersections/uploads")
    return open_junction(name)


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
def intersection_geometry(name: CatalogueName) -> dict[str, Any]:
    """Lanes, junction polygon, medians, crossings, sidewalks and stop lines of one intersection,
    its signal program (what ``lights.phase`` indexes) and which link of it each movement has."""
    junction = catalogue_junction(name)
    return {"name": name, **geometry_with_program(junction)}


def signal_links(junction: Junction) -> dict[str, list[dict[str, Any]]]:
    """Per approach, each signalised movement (entrance lane, turn) and its index into the
    program's state strings: what tells the editor the ego's light in each phase."""
    return {a.id: [{"lane": c.from_lane, "turn": c.turn, "link": c.tl_link_index}
                   for c in a.connections if c.tl_link_index is not None]
            for a in junction.approaches}


def geometry_with_program(junction: Junction) -> dict[str, Any]:
    """The geometry, the signal program and the signal links of a junction."""
    return {**junction_geometry(junction), "program": program_json(junction.net_file, junction.tl_id),
            "signal_links": signal_links(junction)}


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
def internal_lanes(name: CatalogueName) -> dict[str, Any]:
    """How far SUMO's internal lanes run from the candidate paths of the same movements (the
    catalogue's builds draw them along the paths; see ``crossroads net check``)."""
    return internal_lanes_of(catalogue_junction(name), name)


@router.get("/{name}/paths")
def candidate_paths(
    name: CatalogueName,
    task: Literal["left", "straight", "right"],
    approach: Annotated[str | None, Query(max_length=200, description="incoming edge id; default: from the south")] = None,
    rho: Annotated[float | None, Query(gt=0.0, lt=1.0, description=(
        f"ρ of the Bezier construction for every path (the paper: {RHO_BEZIER}); default: chosen "
        "per path within the ego's steering limit"))] = None,
) -> list[dict[str, Any]]:
    """The candidate paths of a task: one per reachable target lane (SPEC §1)."""
    return paths_of(catalogue_junction(name), task, approach, rho)
