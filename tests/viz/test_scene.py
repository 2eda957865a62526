"""3D scene data of the catalogue intersections (crossroads.viz.scene)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crossroads.intersections import catalogue
from crossroads.intersections.resolve import open_junction
from crossroads.perception.sensors import DEFAULT_SENSORS
from crossroads.viz.scene import Mesh, dashes, head_colour, junction_scene, sector_mesh, triangulate
from shapely.geometry import Polygon

NAMES = catalogue.list_intersections()


def test_the_catalogue_has_the_six_intersections() -> None:
    assert len(NAMES) >= 6


@pytest.mark.parametrize("name", NAMES)
def test_scene_covers_the_drivable_area_and_has_its_markings(name: str) -> None:
    junction = open_junction(name)
    scene = junction_scene(junction)
    # the road triangles cover the drivable area (holes kept) within 1 %
    assert scene.road.area() == pytest.approx(junction.drivable_area.area, rel=0.01)
    for mesh in (scene.road, scene.sidewalks, scene.crosswalks):
        assert not mesh.empty
        assert mesh.vertices.dtype == np.float32 and mesh.faces.dtype == np.uint32
        assert int(mesh.faces.max()) < len(mesh.vertices)
    # markings: solid edge borders and the inner (yellow) border of every edge; dashes between
    # the lanes of multi-lane edges
    assert len(scene.solid_lines) > 0 and len(scene.centre_lines) > 0
    edges = [lane.edge_id for lane in junction.lanes.values()]
    multi_lane = len(set(edges)) < len(edges)
    assert (len(scene.dashed_lines) > 0) == multi_lane
    # crosswalks: stripes on each crossing
    assert len(junction.crossings) > 0 and len(scene.crosswalks.faces) >= 2 * len(junction.crossings)
    # stop lines: one per approach; green belts where the network has medians
    assert len(scene.stop_lines) == len(junction.approaches)
    has_median = any(a.median is not None for a in junction.approaches)
    assert (not scene.medians.empty) == has_median
    if has_median:
        medians = sum(a.median.area for a in junction.approaches if a.median is not None)
        assert scene.medians.area() == pytest.approx(medians, rel=0.01)
    # signal heads: at least one per approach, with valid link indices
    assert {h.approach for h in scene.signal_heads} == {a.id for a in junction.approaches}
    for head in scene.signal_heads:
        assert head.link_indices and min(head.link_indices) >= 0
        assert head.position.shape == (3,) and head.position[2] > 2.0


def test_triangulate_keeps_holes() -> None:
    square = Polygon([(0, 0), (10, 0), (10, 10), (0, 10)], holes=[[(4, 4), (6, 4), (6, 6), (4, 6)]])
    mesh = triangulate(square)
    assert mesh.area() == pytest.approx(96.0)
    a, b, c = (mesh.vertices[mesh.faces[:, k], :2] for k in range(3))
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    assert np.all(cross > 0), "faces are counter-clockwise seen from above"
    assert triangulate(None).empty and Mesh.merge([]).empty


def test_sensor_sectors_have_the_right_area() -> None:
    for sensor in DEFAULT_SENSORS:
        mesh = sector_mesh(sensor, n=256)
        expected = 0.5 * sensor.range_m ** 2 * (2 * math.pi if sensor.omnidirectional else sensor.fov_rad)
        assert mesh.area() == pytest.approx(expected, rel=0.01), sensor.name


def test_dashes_paint_half_the_line() -> None:
    segs = dashes(np.array([[0.0, 0.0], [30.0, 0.0]]), dash_m=3.0)
    painted = float(np.sum(np.linalg.norm(segs[:, 1] - segs[:, 0], axis=1)))
    assert painted == pytest.approx(15.0)


def test_head_colour_most_restrictive_wins() -> None:
    assert head_colour("GGrr", (0, 1)) == "green"
    assert head_colour("GgrY", (1,)) == "green"
    assert head_colour("GyGr", (0, 1)) == "yellow"
    assert head_colour("GyGr", (0, 3)) == "red"
    assert head_colour("GG", (5,)) == "off"
