"""A Junction as plain JSON-ready data, for drawing it in the browser or the 3D view.

Coordinates are rounded to the centimetre: enough to draw, and it keeps the payload small.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from crossroads.network.road import Approach, Junction, Lane

_DECIMALS = 2


def _xy(points: np.ndarray) -> list[list[float]]:
    return np.round(np.asarray(points, dtype=float), _DECIMALS).tolist()


def _rings(geometry: BaseGeometry | None) -> list[list[list[float]]]:
    """Exterior rings of a polygon or multipolygon (holes are not needed for drawing)."""
    if geometry is None or geometry.is_empty:
        return []
    polygons = geometry.geoms if isinstance(geometry, MultiPolygon) else [geometry]
    return [_xy(np.asarray(p.exterior.coords)) for p in polygons if isinstance(p, Polygon)]


def _lane(lane: Lane, kind: str) -> dict[str, Any]:
    return {
        "id": lane.id,
        "edge": lane.edge_id,
        "index": lane.index,
        "kind": kind,
        "width_m": round(lane.width_m, 3),
        "speed_limit_mps": round(lane.speed_limit_mps, 3),
        "centerline": _xy(lane.centerline),
    }


def _approach(approach: Approach) -> dict[str, Any]:
    return {
        "id": approach.id,
        "incoming_edge": approach.incoming_edge,
        "outgoing_edge": approach.outgoing_edge,
        "heading_rad": round(approach.heading_rad, 5),
        "entrance_lanes": [
            {**_lane(lane, "entrance"), "turns": sorted(approach.turns_of(lane.id))}
            for lane in approach.entrance_lanes
        ],
        "exit_lanes": [_lane(lane, "exit") for lane in approach.exit_lanes],
        "stop_line": _xy(approach.stop_line),
        "median": _rings(approach.median),
    }


def junction_geometry(junction: Junction) -> dict[str, Any]:
    """Everything needed to draw the intersection, as JSON-ready data."""
    minx, miny, maxx, maxy = junction.drivable_area.bounds
    return {
        "junction_id": junction.id,
        "tl_id": junction.tl_id,
        "center": _xy(junction.center[None, :])[0],
        "bounds": [round(v, _DECIMALS) for v in (minx, miny, maxx, maxy)],
        "polygon": _rings(junction.polygon),
        "default_approach": junction.default_approach().id,
        "approaches": [_approach(a) for a in junction.approaches],
        "crossings": [
            {"id": c.id, "width_m": round(c.width_m, 3), "centerline": _xy(c.centerline),
             "polygon": _rings(c.polygon), "crossed_edges": list(c.crossed_edges)}
            for c in junction.crossings
        ],
        "sidewalks": [_lane(lane, "sidewalk") for lane in junction.sidewalks],
        "bike_lanes": [_lane(lane, "bike") for lane in junction.bike_lanes],
        "walking_areas": [ring for area in junction.walking_areas for ring in _rings(area)],
    }
