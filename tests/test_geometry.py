"""Geometry: the paper's closed form against its construction, the Bezier, resampling, projection."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crossroads.geometry import (
    bezier_control_points_closed_form,
    bezier_control_points_construction,
    cubic_bezier,
    cubic_bezier_derivatives,
    distances_to_polyline,
    arc_lengths,
    hausdorff_distance,
    placed_along,
    heading_curvature_from_derivatives,
    project_onto_polyline,
    resample,
    sample_cubic_bezier,
    sample_cubic_bezier_with_t,
    unit,
    wrap_angle,
    wrap_scalar,
)

angles = st.floats(-math.pi, math.pi, allow_nan=False)
coords = st.floats(-500.0, 500.0, allow_nan=False)
rhos = st.floats(0.05, 0.95)


@settings(max_examples=300, deadline=None)
@given(angles, angles, coords, coords, coords, coords, rhos)
def test_closed_form_equals_construction(th_in, th_out, x1, y1, x4, y4, rho) -> None:
    p1, p4 = np.array([x1, y1]), np.array([x4, y4])
    closed = bezier_control_points_closed_form(p1, p4, th_in, th_out, rho)
    built = bezier_control_points_construction(p1, p4, th_in, th_out, rho)
    scale = 1.0 + float(np.abs(np.concatenate([p1, p4])).max())
    for a, b in zip(closed, built):
        np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-9 * scale)


@settings(max_examples=100, deadline=None)
@given(angles, angles, coords, coords, coords, coords, rhos)
def test_control_points_lie_on_the_lane_lines(th_in, th_out, x1, y1, x4, y4, rho) -> None:
    p1, p4 = np.array([x1, y1]), np.array([x4, y4])
    x2, x3 = bezier_control_points_closed_form(p1, p4, th_in, th_out, rho)
    scale = 1.0 + float(np.abs(np.concatenate([p1, p4])).max())
    cross = lambda d, v: d[0] * v[1] - d[1] * v[0]  # noqa: E731
    assert abs(cross(unit(th_in), x2 - p1)) <= 1e-9 * scale
    assert abs(cross(unit(th_out), x3 - p4)) <= 1e-9 * scale


def test_bezier_endpoints_and_tangents() -> None:
    th_in, th_out = math.radians(90.0), math.radians(180.0)  # a left turn from the south
    x1, x4 = np.array([3.0, -20.0]), np.array([-20.0, 3.0])
    x2, x3 = bezier_control_points_closed_form(x1, x4, th_in, th_out, 0.6)
    cp = np.vstack([x1, x2, x3, x4])
    ends = cubic_bezier(cp, np.array([0.0, 1.0]))
    np.testing.assert_allclose(ends, [x1, x4], atol=1e-12)
    d1, _ = cubic_bezier_derivatives(cp, np.array([0.0, 1.0]))
    np.testing.assert_allclose(d1[0] / np.linalg.norm(d1[0]), unit(th_in), atol=1e-12)
    np.testing.assert_allclose(d1[1] / np.linalg.norm(d1[1]), unit(th_out), atol=1e-12)
    np.testing.assert_allclose(d1[0], 3 * (x2 - x1), atol=1e-12)  # B'(0) = 3(X2 − X1) ∥ θin


def test_analytic_derivatives_match_finite_differences() -> None:
    cp = np.array([[0.0, 0.0], [0.0, 10.0], [-5.0, 20.0], [-20.0, 20.0]])
    t = np.linspace(0.05, 0.95, 19)
    h = 1e-6
    d1, d2 = cubic_bezier_derivatives(cp, t)
    np.testing.assert_allclose(d1, (cubic_bezier(cp, t + h) - cubic_bezier(cp, t - h)) / (2 * h), atol=1e-5)
    np.testing.assert_allclose(
        d2, (cubic_bezier(cp, t + h) - 2 * cubic_bezier(cp, t) + cubic_bezier(cp, t - h)) / h**2, atol=1e-2)


def test_curvature_of_a_circle() -> None:
    r = 7.0
    t = np.linspace(0.0, 1.0, 11)
    d1 = np.column_stack([-r * np.sin(t), r * np.cos(t)])
    d2 = np.column_stack([-r * np.cos(t), -r * np.sin(t)])
    heading, curvature = heading_curvature_from_derivatives(d1, d2)
    np.testing.assert_allclose(curvature, 1.0 / r)
    np.testing.assert_allclose(heading, t + math.pi / 2.0)


@settings(max_examples=50, deadline=None)
@given(angles, angles, rhos, st.floats(5.0, 60.0))
def test_sampled_bezier_spacing(th_in, th_out, rho, dist) -> None:
    x1 = np.zeros(2)
    x4 = dist * unit(th_in + 0.5 * (th_out - th_in))
    cp = np.vstack([x1, *bezier_control_points_closed_form(x1, x4, th_in, th_out, rho), x4])
    for pts in (sample_cubic_bezier(cp, 0.5), sample_cubic_bezier_with_t(cp, 0.5)[0]):
        gaps = np.hypot(*np.diff(pts, axis=0).T)
        assert gaps.max() <= 0.5 + 1e-9
        assert gaps.min() > 0.3  # evenly spaced: no near-duplicates
        np.testing.assert_allclose(pts[[0, -1]], [x1, x4], atol=1e-9)


def test_sample_with_t_points_are_on_the_curve() -> None:
    cp = np.array([[0.0, 0.0], [0.0, 10.0], [-5.0, 20.0], [-20.0, 20.0]])
    pts, t = sample_cubic_bezier_with_t(cp, 0.5)
    np.testing.assert_allclose(pts, cubic_bezier(cp, t), atol=1e-12)
    assert np.all(np.diff(t) > 0.0)


@pytest.mark.parametrize("spacing", [0.5, 0.3, 1.0])
def test_resample_spacing(spacing: float) -> None:
    line = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 7.3], [10.0, 7.3], [3.0, 12.0]])
    pts = resample(line, spacing)
    gaps = np.hypot(*np.diff(pts, axis=0).T)
    assert gaps.max() <= spacing + 1e-9
    np.testing.assert_allclose(pts[[0, -1]], line[[0, -1]])


def test_project_onto_polyline() -> None:
    line = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    i, s, lat = project_onto_polyline(line, (4.0, 1.5))
    assert (i, s, lat) == (0, pytest.approx(4.0), pytest.approx(1.5))  # left of the +x direction
    i, s, lat = project_onto_polyline(line, (11.0, 6.0))
    assert (i, s, lat) == (1, pytest.approx(16.0), pytest.approx(-1.0))  # right of the +y direction
    _, s, lat = project_onto_polyline(line, (-3.0, -2.0))  # behind the start: s clamped
    assert s == 0.0 and lat == pytest.approx(-2.0)


def test_wrap_scalar_is_wrap_angle_on_one_float() -> None:
    for angle in np.linspace(-20.0, 20.0, 401):
        assert wrap_scalar(float(angle)) == pytest.approx(wrap_angle(float(angle)), abs=1e-12)
    assert wrap_scalar(math.pi) == pytest.approx(-math.pi)  # [-π, π), as wrap_angle


def test_distances_to_a_polyline_use_its_segments_and_its_ends() -> None:
    line = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    points = np.array([[5.0, 3.0], [-4.0, 3.0], [12.0, 5.0], [10.0, 0.0]])
    np.testing.assert_allclose(distances_to_polyline(points, line), [3.0, 5.0, 2.0, 0.0])
    np.testing.assert_allclose(distances_to_polyline(points[:1], line[:1]), [math.hypot(5.0, 3.0)])


@given(st.floats(-5.0, 5.0), st.floats(-5.0, 5.0))
@settings(max_examples=50, deadline=None)
def test_hausdorff_distance_of_a_shifted_polyline_is_at_most_the_shift(dx: float, dy: float) -> None:
    arc = np.column_stack([np.cos(np.linspace(0.0, math.pi / 2, 40)),
                           np.sin(np.linspace(0.0, math.pi / 2, 40))]) * 12.0
    shifted = arc + np.array([dx, dy])
    d = hausdorff_distance(arc, shifted)
    assert d <= math.hypot(dx, dy) + 1e-9
    assert hausdorff_distance(shifted, arc) == pytest.approx(d)
    assert hausdorff_distance(arc, arc) == 0.0


def test_a_car_placed_along_a_way_points_from_its_back_to_its_front() -> None:
    # a quarter circle of radius 10 round the origin, from (10, 0) counter-clockwise (1° steps)
    a = np.radians(np.arange(0.0, 91.0))
    way = np.column_stack([10.0 * np.cos(a), 10.0 * np.sin(a)])
    cum = arc_lengths(way)
    x, y, heading = placed_along(way, cum, np.array([10.0]), 4.0)
    front = np.array([10.0 * math.cos(1.0), 10.0 * math.sin(1.0)])  # 10 m along: 1 rad round
    back = np.array([10.0 * math.cos(0.6), 10.0 * math.sin(0.6)])  # the chord to 4 m behind
    chord = math.atan2(*(front - back)[::-1])
    assert heading[0] == pytest.approx(chord, abs=1e-3)
    assert (x[0], y[0]) == pytest.approx(tuple(front - 2.0 * np.array([math.cos(chord), math.sin(chord)])), abs=1e-3)
    # a front less than a length along: its back on the line of the first segment, before the way
    x, y, heading = placed_along(way, cum, np.array([0.1]), 4.0)
    first = math.atan2(way[1, 1] - way[0, 1], way[1, 0] - way[0, 0])
    assert heading[0] == pytest.approx(first, abs=1e-6)
    assert (x[0], y[0]) == pytest.approx(tuple(way[0] - 1.9 * np.array([math.cos(first), math.sin(first)])), abs=1e-6)
