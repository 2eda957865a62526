"""Intersections: the catalogue, the geometry of one (for drawing) and its candidate paths."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, HTTPException, Query

from crossroads.constants import RHO_BEZIER
from crossroads.network import catalogue
from crossroads.network.export import junction_geometry
from crossroads.network.resolve import open_junction
from crossroads.planning import PlanningError, plan_candidates

router = APIRouter(prefix="/intersections", tags=["intersections"])


@router.get("")
def list_intersections() -> list[dict[str, Any]]:
    """The catalogue: every intersection spec shipped under scenarios/intersections/."""
    items = []
    for name in catalogue.list_intersections():
        spec = catalogue.load_spec(name)
        items.append({
            "name": name,
            "description": spec.description,
            "legs": [leg.name for leg in spec.approaches],
        })
    return items


@router.get("/{name}")
def intersection_geometry(name: str) -> dict[str, Any]:
    """Lanes, junction polygon, medians, crossings, sidewalks and stop lines of one intersection."""
    junction = open_junction(name)
    return {"name": name, **junction_geometry(junction)}


@router.get("/{name}/paths")
def candidate_paths(
    name: str,
    task: Literal["left", "straight", "right"],
    approach: Annotated[str | None, Query(description="incoming edge id; default: from the south")] = None,
    rho: Annotated[float, Query(gt=0.0, lt=1.0, description="ρ of the Bezier construction")] = RHO_BEZIER,
) -> list[dict[str, Any]]:
    """The candidate paths of a task: one per reachable target lane (SPEC §1)."""
    junction = open_junction(name)
    try:
        chosen = junction.approach(approach) if approach else junction.default_approach()
    except KeyError as exc:
        raise HTTPException(status_code=422, detail=f"approach: {exc.args[0]}") from exc
    try:
        candidates = plan_candidates(junction, task, approach=chosen, rho=rho)
    except PlanningError as exc:
        raise HTTPException(status_code=422, detail=f"task: {exc}") from exc
    return [c.to_json() for c in candidates]
