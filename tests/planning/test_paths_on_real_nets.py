"""Candidate paths on the paper's six intersections and on real SUMO networks written by others."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import LineString, Point

from crossroads.constants import PATH_SAMPLE_SPACING_M, STOP_SHORT_M, V_LIMIT_MPS
from crossroads.geometry import point_at, polyline_length, project_onto_polyline, wrap_angle
from crossroads.intersections import catalogue
from crossroads.network.road import TASKS
from crossroads.intersections.resolve import open_junction
from crossroads.planning import plan_candidates
from crossroads.planning.curves import MAX_CURVATURE
from crossroads.planning.drivable import road_check
from support import COLOGNE1_NET, SUMO_CROSS_NET, SUMO_RL_NET, sumo_example

CATALOGUE = catalogue.list_intersections()
REAL_NETS = {
    "cologne1": COLOGNE1_NET,
    "sumo-rl-2way": SUMO_RL_NET,
    "sumo-game-cross": sumo_example(SUMO_CROSS_NET),
}
# How far a path's centre line may leave the drivable area [m]. SUMO rounds junction corners on
# hand-drawn nets; the catalogue's own nets must contain the paths exactly (up to sampling).
ROAD_TOLERANCE_M = {"catalogue": 0.05, "real": 0.75}


def candidates_of(ref):
    junction = open_junction(ref)
    return junction, {task: plan_candidates(junction, task) for task in TASKS
                      if junction.default_approach().connections_for(task)}


@pytest.mark.parametrize("name", CATALOGUE)
def test_counts_match_the_spec(name: str) -> None:
    expected = catalogue.load_spec(name).expected_candidates
    _, by_task = candidates_of(name)
    assert {task: len(c) for task, c in by_task.items()} == dict(expected)


@pytest.mark.parametrize(
    ("ref", "kind"),
    [(name, "catalogue") for name in CATALOGUE] + [(str(p), "real") for p in REAL_NETS.values()],
    ids=CATALOGUE + list(REAL_NETS),
)
def test_paths_are_continuous_on_their_lanes_and_on_the_road(ref: str, kind: str) -> None:
    junction, by_task = candidates_of(ref)
    assert by_task, "the default approach allows at least one task"
    road = junction.drivable_area.buffer(ROAD_TOLERANCE_M[kind])
    for candidates in by_task.values():
        for c in candidates:
            lead_in = junction.lead_in(c.entrance_lane).centerline
            lead_out = junction.lead_out(c.exit_lane).centerline
            gaps = np.hypot(*np.diff(c.points, axis=0).T)
            assert gaps.max() <= PATH_SAMPLE_SPACING_M + 1e-9, c.id
            # X0 and X1 on the road into the entrance lane, X4 and X5 on the road on from the exit
            for point, line in ((c.control_points[0], lead_in), (c.control_points[1], lead_in),
                                (c.control_points[4], lead_out), (c.control_points[5], lead_out)):
                assert LineString(line).distance(Point(point)) < 0.06, c.id
            np.testing.assert_allclose(c.points[0], c.control_points[0], atol=1e-9)
            np.testing.assert_allclose(c.points[-1], c.control_points[5], atol=1e-9)
            # X1 and X4 at the lanes' ends unless moved (and then never further than 10 m)
            assert (c.x1_shift_m > 0.0) == (np.hypot(*(c.control_points[1] - lead_in[-1])) > 1e-6), c.id
            assert (c.x4_shift_m > 0.0) == (np.hypot(*(c.control_points[4] - lead_out[0])) > 1e-6), c.id
            assert max(c.x1_shift_m, c.x4_shift_m) <= 10.0
            # headings at X1 and X4 equal the lanes' directions there
            i1 = int(np.argmin(np.hypot(*(c.points - c.control_points[1]).T)))
            i4 = int(np.argmin(np.hypot(*(c.points - c.control_points[4]).T)))
            _, s1, _ = project_onto_polyline(lead_in, c.control_points[1])
            _, s4, _ = project_onto_polyline(lead_out, c.control_points[4])
            for i, line, s_m in ((i1, lead_in, s1), (i4, lead_out, s4)):
                ahead = point_at(line, min(s_m + 0.5, polyline_length(line)))
                behind = point_at(line, max(s_m - 0.5, 0.0))
                assert abs(wrap_angle(c.heading[i] - np.arctan2(*(ahead - behind)[::-1]))) < 0.03, c.id
            # a car can drive the curve: within the steering limit, its footprint on the road
            assert c.max_curvature <= MAX_CURVATURE + 1e-6, (c.id, c.max_curvature)
            outside = [p for p in c.points if not road.contains(Point(p))]
            assert not outside, f"{c.id} leaves the road at {outside[:3]}"
            curve = c.segment == "curve"
            assert road_check(junction, c.approach).problem(c.points[curve], c.heading[curve]) is None


@pytest.mark.parametrize("name", CATALOGUE)
def test_speed_profiles_at_their_key_points(name: str) -> None:
    _, by_task = candidates_of(name)
    for c in by_task["left"]:
        curve = c.segment == "curve"
        cruise, inside = 0.8 * V_LIMIT_MPS, min(0.5 * V_LIMIT_MPS, 30 / 3.6)
        assert np.allclose(c.v_pass[c.segment == "entrance"], cruise)
        assert np.allclose(c.v_pass[curve], inside)
        assert np.allclose(c.v_pass[c.segment == "exit"], cruise)
        assert np.allclose(c.v_stop[curve], 0.0)
        assert np.allclose(c.v_stop[c.segment == "exit"], cruise)
        # distance to where the centre stands with the front bumper on the stop line
        d = c.s_stop_line - STOP_SHORT_M - c.s
        entrance = c.segment == "entrance"
        far, near, rest = entrance & (d >= 30.0), entrance & (d < 30.0) & (d > 0.0), entrance & (d <= 0.0)
        assert np.allclose(c.v_stop[far], cruise)
        assert np.allclose(c.v_stop[near], cruise * np.sqrt(d[near] / 30.0))
        assert rest.any() and np.allclose(c.v_stop[rest], 0.0)  # the bumper's last 2.4 m to the line


@pytest.mark.parametrize("name", CATALOGUE)
def test_every_catalogue_path_is_within_the_ego_s_steering_limit(name: str) -> None:
    """Issue 36: the catalogue's geometry is ours, so every candidate of every approach and task
    bends no tighter than the ego can steer, with its own ends (the specs' 6 m kerbs make room:
    no X1/X4 moved), and SUMO's internal lanes are drawn along them (the build's shapes)."""
    from crossroads.planning.internal_lanes import internal_lane_offsets

    junction = open_junction(name)
    for approach in junction.approaches:
        for task in TASKS:
            if not approach.connections_for(task):
                continue
            for c in plan_candidates(junction, task, approach=approach):
                assert c.max_curvature <= MAX_CURVATURE, (approach.id, c.id, c.max_curvature)
                assert (c.x1_shift_m, c.x4_shift_m) == (0.0, 0.0), (approach.id, c.id)
    offsets = [o for o in internal_lane_offsets(junction) if o.max_m is not None]
    assert offsets and max(o.max_m for o in offsets) < 0.05
    assert catalogue.load_spec(name).kerb_radius_m == 6.0
