"""Sensor coverage (SPEC §3): lidar 70 m 360°, camera 80 m ±35°, radars 60 m ±45°."""

from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import Point, Polygon

from crossroads.constants import (
    CAMERA_RANGE_M, DEG, EGO_LENGTH_M, LIDAR_RANGE_M, RADAR_CORNER_YAW_DEG, RADAR_RANGE_M,
)
from crossroads.perception.sensors import DEFAULT_SENSORS, Sensor, covered, sector_polygon


def test_default_sensors() -> None:
    names = [s.name for s in DEFAULT_SENSORS]
    assert names.count("lidar") == 1 and names.count("camera") == 1
    radars = [s for s in DEFAULT_SENSORS if s.name.startswith("radar")]
    assert len(radars) == 3 and all(r.range_m == RADAR_RANGE_M for r in radars)
    assert sorted(round(r.yaw_rad / DEG) for r in radars) == [-RADAR_CORNER_YAW_DEG, 0, RADAR_CORNER_YAW_DEG]
    lidar = next(s for s in DEFAULT_SENSORS if s.name == "lidar")
    camera = next(s for s in DEFAULT_SENSORS if s.name == "camera")
    assert lidar.omnidirectional and lidar.range_m == LIDAR_RANGE_M
    assert camera.fov_rad == pytest.approx(70 * DEG) and camera.yaw_rad == 0.0
    with pytest.raises(Exception):
        camera.range_m = 1.0  # frozen


def test_union_of_the_sectors() -> None:
    # ego at (10, 5) heading north: ahead is +y
    ex, ey, h = 10.0, 5.0, math.pi / 2
    cam_x = EGO_LENGTH_M / 4.0
    pts = {
        "ahead 75 m (camera only)": ((ex, ey + cam_x + 75.0), True),
        "ahead 79 m of the camera": ((ex, ey + cam_x + 79.0), True),
        "ahead 81 m of the camera": ((ex, ey + cam_x + 81.0), False),
        "behind 65 m (lidar)": ((ex, ey - 65.0), True),
        "behind 75 m": ((ex, ey - 75.0), False),
        "left 69 m (lidar)": ((ex - 69.0, ey), True),
        "75 m at 30° off the axis (camera)": ((ex - 75 * math.sin(30 * DEG), ey + cam_x + 75 * math.cos(30 * DEG)), True),
        "75 m at 40° off the axis": ((ex + 75 * math.sin(40 * DEG), ey + cam_x + 75 * math.cos(40 * DEG)), False),
    }
    xs = np.array([p[0][0] for p in pts.values()])
    ys = np.array([p[0][1] for p in pts.values()])
    mask = covered(ex, ey, h, xs, ys)
    for (name, (_, expected)), got in zip(pts.items(), mask):
        assert got == expected, name
    assert covered(ex, ey, h, [], []).shape == (0,)


def test_rotation_invariance_and_single_sensors() -> None:
    rng = np.random.default_rng(0)
    local = rng.uniform(-90, 90, size=(2000, 2))
    base = covered(0.0, 0.0, 0.0, local[:, 0], local[:, 1])
    for heading in (0.3, 2.0, -2.9):
        c, s = math.cos(heading), math.sin(heading)
        wx = 5.0 + c * local[:, 0] - s * local[:, 1]
        wy = -3.0 + s * local[:, 0] + c * local[:, 1]
        np.testing.assert_array_equal(covered(5.0, -3.0, heading, wx, wy), base)
    # a radar alone: 60 m, ±45° around its facing direction from its mount
    radar = Sensor("r", RADAR_RANGE_M, 90 * DEG, mount_x_m=2.0, mount_y_m=1.0, yaw_rad=45 * DEG)
    got = covered(0.0, 0.0, 0.0, local[:, 0], local[:, 1], (radar,))
    rel = local - [2.0, 1.0]
    bearing = np.degrees(np.arctan2(rel[:, 1], rel[:, 0]))
    expected = (np.hypot(*rel.T) <= RADAR_RANGE_M) & (bearing >= 0.0) & (bearing <= 90.0)
    np.testing.assert_array_equal(got, expected)


def test_sector_polygons_match_coverage() -> None:
    rng = np.random.default_rng(1)
    ex, ey, h = 3.0, 4.0, 1.0
    for sensor in DEFAULT_SENSORS:
        poly = sector_polygon(sensor, ex, ey, h, n=256)
        if sensor.omnidirectional:
            assert poly.shape == (256, 2)
            np.testing.assert_allclose(np.hypot(poly[:, 0] - ex, poly[:, 1] - ey), sensor.range_m)
        else:
            assert poly.shape == (258, 2)
        shape = Polygon(poly)
        pts = rng.uniform(-90, 90, size=(3000, 2)) + [ex, ey]
        mask = covered(ex, ey, h, pts[:, 0], pts[:, 1], (sensor,))
        inside = np.array([shape.contains(Point(p)) for p in pts])
        boundary = np.array([shape.exterior.distance(Point(p)) < 0.5 for p in pts])
        np.testing.assert_array_equal(mask[~boundary], inside[~boundary])
    assert CAMERA_RANGE_M > LIDAR_RANGE_M > RADAR_RANGE_M


def _covered_sensor_by_sensor(ex, ey, h, xs, ys, sensors):
    """Every sensor's own sector test on the points within its reach, OR-ed (covered() without
    its shortcuts: the skipped radars, the all-round sensor on the offsets, the shared distances)."""
    mask = np.zeros(len(xs), dtype=bool)
    distance = np.hypot(xs - ex, ys - ey)
    for sensor in sensors:
        rest = np.flatnonzero(~mask & (distance <= sensor.range_m + math.hypot(sensor.mount_x_m, sensor.mount_y_m)))
        if len(rest):
            mask[rest] = sensor.covers(ex, ey, h, xs[rest], ys[rest])
    return mask


def test_shortcuts_change_nothing() -> None:
    rng = np.random.default_rng(2)
    odd = (Sensor("far radar", 90.0, 60 * DEG, mount_x_m=2.0, yaw_rad=0.5),
           Sensor("off-centre lidar", 65.0, 2 * math.pi, mount_x_m=1.0),
           Sensor("short lidar", 30.0, 2 * math.pi))
    for sensors in (DEFAULT_SENSORS, odd, odd[::-1], (DEFAULT_SENSORS[1],), list(DEFAULT_SENSORS)):
        for _ in range(20):
            ex, ey, h = rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(-4, 4)
            # around the ranges' edges too, where rounding decides
            r = np.concatenate([rng.uniform(0, 95, 300), rng.choice([30.0, 60.0, 65.0, 70.0, 80.0, 90.0], 100)
                                + rng.normal(0, 1e-9, 100)])
            a = rng.uniform(-math.pi, math.pi, len(r))
            xs, ys = ex + r * np.cos(a), ey + r * np.sin(a)
            expected = _covered_sensor_by_sensor(ex, ey, h, xs, ys, tuple(sensors))
            np.testing.assert_array_equal(covered(ex, ey, h, xs, ys, sensors), expected)
            dx, dy = xs - ex, ys - ey
            np.testing.assert_array_equal(
                covered(ex, ey, h, xs, ys, sensors, relative=(dx, dy, np.hypot(dx, dy))), expected)
