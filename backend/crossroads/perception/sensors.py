"""The ego's sensors (SPEC §3, paper Sec. IV-B): which participants it perceives.

Sensors (range, horizontal field of view from ``constants``): one lidar (70 m, 360°), one camera
(80 m, ±35°) and three radars (60 m, ±45°). **(choice)** Mounting, in the ego frame (x forward,
y left, origin at the ego's centre): the lidar on the roof at the centre; the camera behind the
windscreen (a quarter length ahead of the centre) facing forward; one radar at the middle of the
front bumper facing forward and two at the front corners facing ±45° outward.

A participant is perceived when its reference point (the centre SUMO reports) lies in the sector
of at least one sensor: within the range of the sensor's mount point and within half the field
of view of its facing direction. Occlusion is not modelled (the paper does not mention it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from crossroads.constants import (
    CAMERA_FOV_DEG,
    CAMERA_RANGE_M,
    DEG,
    EGO_LENGTH_M,
    EGO_WIDTH_M,
    LIDAR_FOV_DEG,
    LIDAR_RANGE_M,
    RADAR_CORNER_YAW_DEG,
    RADAR_FOV_DEG,
    RADAR_RANGE_M,
)
from crossroads.geometry import FloatArray


@dataclass(frozen=True)
class Sensor:
    """One sensor: its range, full horizontal field of view and mounting in the ego frame."""

    name: str
    range_m: float  # [m]
    fov_rad: float  # [rad] full horizontal field of view (2π: all around)
    mount_x_m: float = 0.0  # [m] ahead of the ego's centre
    mount_y_m: float = 0.0  # [m] left of the ego's centre
    yaw_rad: float = 0.0  # [rad] facing direction relative to the ego's heading, CCW

    @property
    def omnidirectional(self) -> bool:
        return self.fov_rad >= 2.0 * math.pi - 1e-12

    def mount_world(self, ego_x: float, ego_y: float, ego_heading: float) -> tuple[float, float, float]:
        """The mount point (x, y) [m] and facing direction [rad] in the world frame."""
        c, s = math.cos(ego_heading), math.sin(ego_heading)
        return (ego_x + c * self.mount_x_m - s * self.mount_y_m,
                ego_y + s * self.mount_x_m + c * self.mount_y_m,
                ego_heading + self.yaw_rad)

    def covers(self, ego_x: float, ego_y: float, ego_heading: float, xs: ArrayLike, ys: ArrayLike) -> np.ndarray:
        """Boolean mask of the points (xs, ys) inside this sensor's sector."""
        mx, my, facing = self.mount_world(ego_x, ego_y, ego_heading)
        dx = np.asarray(xs, dtype=np.float64) - mx
        dy = np.asarray(ys, dtype=np.float64) - my
        inside = dx * dx + dy * dy <= self.range_m * self.range_m
        if self.omnidirectional:
            return inside
        bearing = np.mod(np.arctan2(dy, dx) - facing + math.pi, 2.0 * math.pi) - math.pi
        return inside & (np.abs(bearing) <= 0.5 * self.fov_rad)


_FRONT_M = EGO_LENGTH_M / 2.0
_SIDE_M = EGO_WIDTH_M / 2.0

DEFAULT_SENSORS: tuple[Sensor, ...] = (
    Sensor("lidar", LIDAR_RANGE_M, LIDAR_FOV_DEG * DEG),
    Sensor("camera", CAMERA_RANGE_M, CAMERA_FOV_DEG * DEG, mount_x_m=EGO_LENGTH_M / 4.0),
    Sensor("radar-front", RADAR_RANGE_M, RADAR_FOV_DEG * DEG, mount_x_m=_FRONT_M),
    Sensor("radar-front-left", RADAR_RANGE_M, RADAR_FOV_DEG * DEG, mount_x_m=_FRONT_M, mount_y_m=_SIDE_M,
           yaw_rad=RADAR_CORNER_YAW_DEG * DEG),
    Sensor("radar-front-right", RADAR_RANGE_M, RADAR_FOV_DEG * DEG, mount_x_m=_FRONT_M, mount_y_m=-_SIDE_M,
           yaw_rad=-RADAR_CORNER_YAW_DEG * DEG),
)


def covered(
    ego_x: float, ego_y: float, ego_heading: float, xs: ArrayLike, ys: ArrayLike,
    sensors: Sequence[Sensor] = DEFAULT_SENSORS, *,
    relative: tuple[FloatArray, FloatArray, FloatArray] | None = None,
) -> np.ndarray:
    """Boolean mask: which points (xs, ys) [m] any of the sensors covers (the union of sectors).

    ``relative``: ``(xs - ego_x, ys - ego_y, np.hypot of those two)`` when the caller has them
    already (the world computes them once a step for perception, the front-vehicle check and the
    collision judge).
    """
    xs = np.asarray(xs, dtype=np.float64)
    ys = np.asarray(ys, dtype=np.float64)
    if relative is None:
        dx, dy = xs - ego_x, ys - ego_y
        relative = (dx, dy, np.hypot(dx, dy))  # [m] from the ego's centre
    dx, dy, distance = relative
    mask: np.ndarray | None = None  # None: nothing covered yet
    for sensor, reach, centred in _plan(sensors):
        within = distance <= reach
        if centred:
            # all round from the ego's centre (the lidar): Sensor.covers on the offsets themselves
            # (its mount point is the ego's centre), for every point at once: no index juggling
            hit = within & (dx * dx + dy * dy <= sensor.range_m * sensor.range_m)
            mask = hit if mask is None else mask | hit
            continue
        # only the points no earlier sensor covers (the lidar alone covers most of them) and that
        # this sensor can reach at all from its mount
        rest = (within if mask is None else within & ~mask).nonzero()[0]
        if mask is None:
            mask = np.zeros(xs.shape, dtype=bool)
        if len(rest) == 0:
            continue
        mask[rest] = sensor.covers(float(ego_x), float(ego_y), float(ego_heading), xs[rest], ys[rest])
    return mask if mask is not None else np.zeros(xs.shape, dtype=bool)


_Plan = tuple[tuple[Sensor, float, bool], ...]
_PLANS: dict[int, tuple[tuple[Sensor, ...], _Plan]] = {}  # id of a sensors tuple -> (it, its plan)


def _plan(sensors: Sequence[Sensor]) -> _Plan:
    """:func:`_contributing` of a set of sensors, remembered by the identity of the tuple (the
    world passes the same DEFAULT_SENSORS every step: no hashing of five dataclasses each time)."""
    key = sensors if isinstance(sensors, tuple) else tuple(sensors)
    hit = _PLANS.get(id(key))
    if hit is not None and hit[0] is key:  # the stored tuple is kept alive, so its id is its own
        return hit[1]
    if len(_PLANS) >= 16:
        _PLANS.clear()
    plan = _contributing(key)
    _PLANS[id(key)] = (key, plan)
    return plan


def _contributing(sensors: tuple[Sensor, ...]) -> _Plan:
    """The sensors that can cover a point no other one covers, each with its reach [m] from the
    ego's centre (range + distance of its mount) and whether it is all round from the centre.

    The union does not depend on the order the sectors are tested in, so a sensor is left out when
    an all-round one mounted at the centre reaches clearly further (the default radars: 62.6 m
    against the lidar's 70 m): every point it could cover, that one covers already (the margin is
    far beyond the rounding of distance against range²). Saves their array operations every step.
    """
    def centred(s: Sensor) -> bool:
        return s.omnidirectional and s.mount_x_m == 0.0 and s.mount_y_m == 0.0

    reach = [s.range_m + math.hypot(s.mount_x_m, s.mount_y_m) for s in sensors]
    return tuple(
        (s, r, centred(s)) for s, r in zip(sensors, reach)
        if not any(centred(o) and r < o.range_m * (1.0 - 1e-9) for o in sensors if o is not s))


def sector_polygon(sensor: Sensor, ego_x: float, ego_y: float, ego_heading: float, n: int = 48) -> FloatArray:
    """Outline (M, 2) of a sensor's sector in the world frame, for drawing.

    A full circle of ``n`` points for an all-round sensor; otherwise the mount point followed by
    ``n + 1`` points along the arc (close it by repeating the first point if needed).
    """
    mx, my, facing = sensor.mount_world(float(ego_x), float(ego_y), float(ego_heading))
    if sensor.omnidirectional:
        angles = facing + np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
        return np.column_stack([mx + sensor.range_m * np.cos(angles), my + sensor.range_m * np.sin(angles)])
    angles = facing + np.linspace(-0.5 * sensor.fov_rad, 0.5 * sensor.fov_rad, n + 1)
    arc = np.column_stack([mx + sensor.range_m * np.cos(angles), my + sensor.range_m * np.sin(angles)])
    return np.vstack([[mx, my], arc])
