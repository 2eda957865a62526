"""Whether a candidate's curve stays where a car may drive (checked before the path is offered).

A curve route through the junction must keep the ego's footprint on the road, and must not run
over another approach's entrance lanes, where the other approach's traffic waits at its stop line.
The first fails on real nets whose junction outline SUMO draws tight; the second where SUMO models
one intersection as two nodes and a left turn's Bezier, drawn between far-apart lane ends, cuts
across the opposite approach (19 m off SUMO's own lane on one city net).

Rules (choices):

- **Footprint on the road.** At every sample of the curve, the four corners of the ego's footprint
  (its centre on the path, its axis along the path's heading) lie within the junction's drivable
  area grown by :data:`ROAD_MARGIN_M` (0.5 m), the overhang the world's judge allows a corner
  before it calls the episode ``off_road`` (kerbs, paint).
- **Off other entrances.** No sample of the curve's centre line lies more than
  :data:`FOREIGN_LANE_DEPTH_M` inside an entrance lane of another approach: grazing the corner of
  a lane end is the geometry of every tight junction, driving along it is not.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from crossroads.constants import EGO_LENGTH_M, EGO_WIDTH_M
from crossroads.geometry import FloatArray
from crossroads.network.road import Approach, Junction

ROAD_MARGIN_M = 0.5  # [m] a footprint corner may overhang the drivable area this much
FOREIGN_LANE_DEPTH_M = 0.25  # [m] how far inside another approach's entrance lane counts as on it


def footprint_corners(points: FloatArray, headings: FloatArray) -> tuple[FloatArray, FloatArray]:
    """x and y [m] of the ego's four footprint corners at every pose, as ``(N * 4,)`` arrays."""
    c, s = np.cos(headings)[:, None], np.sin(headings)[:, None]
    along = np.array([1.0, 1.0, -1.0, -1.0])[None, :] * (EGO_LENGTH_M / 2.0)
    across = np.array([1.0, -1.0, -1.0, 1.0])[None, :] * (EGO_WIDTH_M / 2.0)
    xs = points[:, :1] + along * c - across * s
    ys = points[:, 1:2] + along * s + across * c
    return xs.ravel(), ys.ravel()


@dataclass(frozen=True)
class _Area:
    name: str
    geometry: BaseGeometry


class RoadCheck:
    """The drivable area and the other approaches' entrance lanes of one approach's candidates."""

    def __init__(self, junction: Junction, approach: Approach) -> None:
        self.road = junction.drivable_area.buffer(ROAD_MARGIN_M)
        shapely.prepare(self.road)
        self.foreign: list[_Area] = []
        for other in junction.approaches:
            if other.id == approach.id:
                continue
            lanes = shapely.union_all([lane.polygon() for lane in other.entrance_lanes])
            inner = lanes.buffer(-FOREIGN_LANE_DEPTH_M)
            if inner.is_empty:
                continue
            shapely.prepare(inner)
            self.foreign.append(_Area(other.id, inner))

    def fits(self, points: FloatArray, headings: FloatArray) -> bool:
        """Whether a curve (its samples and headings) keeps to the road: :meth:`problem` is None
        (the quick test: no distances measured)."""
        xs, ys = footprint_corners(points, headings)
        if not shapely.contains_xy(self.road, xs, ys).all():
            return False
        return not any(shapely.contains_xy(a.geometry, points[:, 0], points[:, 1]).any()
                       for a in self.foreign)

    def problem(self, points: FloatArray, headings: FloatArray) -> str | None:
        """Why a curve (its samples and headings) is no place to drive, or None when it is."""
        xs, ys = footprint_corners(points, headings)
        outside = ~shapely.contains_xy(self.road, xs, ys)
        if outside.any():
            corners = np.column_stack([xs[outside], ys[outside]])
            # the corner farthest from the path's own samples is the one farthest off the road,
            # near enough: one distance to the (large) road polygon measured, not one per corner
            far = int(np.argmax(np.min(np.hypot(corners[:, None, 0] - points[None, :, 0],
                                                corners[:, None, 1] - points[None, :, 1]), axis=1)))
            x, y = corners[far]
            gap = float(shapely.distance(self.road, shapely.points(x, y)))
            return (f"the ego's footprint leaves the drivable area by {gap + ROAD_MARGIN_M:.1f} m "
                    f"near ({x:.1f}, {y:.1f})")
        for area in self.foreign:
            on = shapely.contains_xy(area.geometry, points[:, 0], points[:, 1])
            if on.any():
                x, y = points[int(np.argmax(on))]
                return (f"it runs over the entrance lanes of approach {area.name!r} near "
                        f"({x:.1f}, {y:.1f})")
        return None


@lru_cache(maxsize=32)
def road_check(junction: Junction, approach_id: str) -> RoadCheck:
    """The :class:`RoadCheck` of one approach (cached: junctions are immutable and hashed by
    identity, and a check prepares its geometry once)."""
    return RoadCheck(junction, junction.approach(approach_id))
