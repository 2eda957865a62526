"""Candidate paths on synthetic junctions (tests/planning/factories.py), SPEC §1."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from shapely.geometry import LineString, Point

from crossroads.constants import PATH_SAMPLE_SPACING_M, RHO_BEZIER
from crossroads.geometry import bezier_control_points_construction, wrap_angle
from crossroads.planning import CandidatePath, PlanningError, plan_candidates
from crossroads.planning.curves import MAX_CURVATURE, PAPER_RHO_MAX_CURVATURE
from planning.factories import four_way_junction

LAYOUTS = {
    "1-lane": dict(n_lanes=1),
    "2-lane": dict(n_lanes=2),
    "3-lane-median": dict(n_lanes=3, median_m=3.0),
    "skewed": dict(n_lanes=2, leg_angles_deg=(-100.0, 10.0, 75.0, 200.0)),
    "rotated": dict(n_lanes=2, leg_angles_deg=(-60.0, 30.0, 120.0, 210.0)),
}
TASKS = ("left", "straight", "right")


def all_candidates(junction, rho: float | None = None) -> list[CandidatePath]:
    return [c for task in TASKS for c in plan_candidates(junction, task, rho=rho)]


@pytest.fixture(params=list(LAYOUTS), scope="module")
def junction(request):
    return four_way_junction(**LAYOUTS[request.param])


def test_counts_equal_reachable_target_lanes(junction) -> None:
    approach = junction.default_approach()
    for task in TASKS:
        targets = {c.to_lane for c in approach.connections_for(task)}
        cands = plan_candidates(junction, task)
        assert len(cands) == len(targets)
        assert {c.exit_lane for c in cands} == targets
        assert [c.id for c in cands] == [f"{task}-{k}" for k in range(len(cands))]


def test_three_left_candidates_for_three_target_lanes() -> None:
    assert len(plan_candidates(four_way_junction(n_lanes=3), "left")) == 3


def test_continuity_and_sampling(junction) -> None:
    for c in all_candidates(junction):
        gaps = np.hypot(*np.diff(c.points, axis=0).T)
        assert gaps.max() <= PATH_SAMPLE_SPACING_M + 1e-9, c.id
        assert gaps.min() > 1e-3, f"{c.id}: duplicate points"
        np.testing.assert_allclose(np.diff(c.s), gaps)
        assert c.s[0] == 0.0
        # heading continuous: no jump larger than what 0.5 m at the sharpest curvature allows
        dh = np.abs(wrap_angle(np.diff(c.heading)))
        assert dh.max() <= PATH_SAMPLE_SPACING_M * np.abs(c.curvature).max() + 1e-6, c.id
        # finite, bounded; turns sharper than 90° (skewed legs) get tight ends of the paper's Bezier
        assert np.all(np.isfinite(c.curvature)) and np.abs(c.curvature).max() < 1.0


def test_headings_at_the_joins_equal_the_lane_directions(junction) -> None:
    for c in all_candidates(junction):
        ent, ext = junction.lanes[c.entrance_lane], junction.lanes[c.exit_lane]
        i1 = int(np.flatnonzero(np.isclose(c.s, c.s_stop_line))[0])
        i4 = int(np.flatnonzero(np.isclose(c.s, c.s_exit))[0])
        for i in (i1 - 1, i1):  # the last entrance point and X1
            assert abs(wrap_angle(c.heading[i] - ent.end_heading)) < 1e-3, (c.id, i)
        for i in (i4, i4 + 1):  # X4 and the first exit point
            assert abs(wrap_angle(c.heading[i] - ext.start_heading)) < 1e-3, (c.id, i)


def test_control_points_and_segments(junction) -> None:
    """The paper's construction, ρ fixed at 0.6 for every candidate."""
    for c in all_candidates(junction, rho=RHO_BEZIER):
        assert c.rho == RHO_BEZIER and (c.x1_shift_m, c.x4_shift_m) == (0.0, 0.0)
        ent, ext = junction.lanes[c.entrance_lane], junction.lanes[c.exit_lane]
        x0, x1, x2, x3, x4, x5 = c.control_points
        np.testing.assert_allclose(x1, ent.end, atol=1e-9)
        np.testing.assert_allclose(x4, ext.start, atol=1e-9)
        np.testing.assert_allclose(c.points[0], x0)
        np.testing.assert_allclose(c.points[-1], x5)
        assert LineString(ent.centerline).distance(Point(x0)) < 1e-9
        assert LineString(ext.centerline).distance(Point(x5)) < 1e-9
        assert np.hypot(*(x1 - x0)) == pytest.approx(50.0)
        assert np.hypot(*(x5 - x4)) == pytest.approx(30.0)
        want = bezier_control_points_construction(x1, x4, ent.end_heading, ext.start_heading, RHO_BEZIER)
        np.testing.assert_allclose([x2, x3], want, atol=1e-9)
        seg = list(c.segment)
        assert seg == sorted(seg, key=("entrance", "curve", "exit").index)
        assert c.segment[np.isclose(c.s, c.s_stop_line)][0] == "entrance"
        assert c.s_stop_line == pytest.approx(50.0)
        # each route lies on its lane
        ent_line, ext_line = LineString(ent.centerline), LineString(ext.centerline)
        assert max(ent_line.distance(Point(p)) for p in c.points[c.segment == "entrance"]) < 1e-9
        assert max(ext_line.distance(Point(p)) for p in c.points[c.segment == "exit"]) < 1e-9


def test_chosen_rho_keeps_every_curve_within_the_steering_limit(junction) -> None:
    """The default: ρ per candidate, the paper's where its curve bends gently (straight on), and
    every curve within the ego's 0.16 1/m; ``max_curvature`` is the curve route's own."""
    paper = all_candidates(junction, rho=RHO_BEZIER)
    chosen = all_candidates(junction)
    assert max(c.max_curvature for c in paper) > MAX_CURVATURE  # the paper's ρ bends too tight here
    for p, c in zip(paper, chosen, strict=True):
        curve = c.segment == "curve"
        assert c.max_curvature == pytest.approx(np.abs(c.curvature[curve]).max())
        assert c.max_curvature <= MAX_CURVATURE and not c.exceeds_limit, c.id
        if p.max_curvature <= PAPER_RHO_MAX_CURVATURE:
            assert c.rho == RHO_BEZIER and c.max_curvature == pytest.approx(p.max_curvature), c.id
        else:
            assert c.rho != RHO_BEZIER and c.max_curvature < p.max_curvature, c.id


def test_candidates_stay_on_the_road(junction) -> None:
    road = junction.drivable_area.buffer(0.05)
    for c in all_candidates(junction):
        assert road.contains(LineString(c.points)), c.id


def test_entrance_lane_follows_lateral_order() -> None:
    # two lanes may turn left (lane 0 and lane 1 both reach both left targets)
    extra = [(0, 0, "left", 0), (0, 0, "left", 1), (0, 1, "left", 0)]
    j = four_way_junction(n_lanes=2, extra=extra)
    cands = plan_candidates(j, "left")
    assert [(c.entrance_lane, c.exit_lane) for c in cands] == [("in0_0", "out3_0"), ("in0_1", "out3_1")]
    only = plan_candidates(j, "left", entrance_lane="in0_1")
    assert [(c.entrance_lane, c.exit_lane) for c in only] == [("in0_1", "out3_0"), ("in0_1", "out3_1")]


def test_bending_lanes_are_followed() -> None:
    j = four_way_junction(n_lanes=1)
    ent = j.lanes["in0_0"]
    # bend the entrance lane: the first part comes in at an angle
    bent = np.vstack([ent.start + np.array([-15.0, 0.0]), ent.start + np.array([0.0, 40.0]), ent.end])
    object.__setattr__(ent, "centerline", bent)
    (c,) = plan_candidates(j, "straight", entrance_length_m=1000.0)
    np.testing.assert_allclose(c.points[0], bent[0])
    # resampling at 0.5 m cuts the lane's corner by a few centimetres at most
    assert c.s_stop_line == pytest.approx(np.hypot(15.0, 40.0) + np.hypot(*(ent.end - bent[1])), abs=0.05)
    assert max(LineString(bent).distance(Point(p)) for p in c.points[c.segment == "entrance"]) < 0.05


def test_short_lanes_clamp_routes() -> None:
    j = four_way_junction(n_lanes=1)
    (c,) = plan_candidates(j, "right", entrance_length_m=500.0, exit_length_m=500.0)
    np.testing.assert_allclose(c.control_points[0], j.lanes["in0_0"].start)
    np.testing.assert_allclose(c.control_points[5], j.lanes[c.exit_lane].end)


def test_project_and_nearest() -> None:
    (c,) = plan_candidates(four_way_junction(n_lanes=1), "right")
    i = len(c.points) // 2
    h = c.heading[i]
    normal_left = np.array([-math.sin(h), math.cos(h)])
    p = c.points[i] + 0.3 * normal_left
    proj = c.project(*p)
    assert proj.s_m == pytest.approx(c.s[i], abs=1e-2)
    assert proj.lateral_m == pytest.approx(0.3, abs=1e-2)
    assert abs(wrap_angle(proj.heading_rad - h)) < 1e-2
    assert c.nearest(*(c.points[i] - 0.2 * normal_left)) == i
    x, y, heading, v = c.reference_at(c.s[i], "pass")
    assert (x, y) == (pytest.approx(c.points[i][0]), pytest.approx(c.points[i][1]))
    assert v == pytest.approx(c.v_pass[i])


def test_to_json_round_trips() -> None:
    for c in plan_candidates(four_way_junction(n_lanes=2), "left"):
        data = json.loads(json.dumps(c.to_json()))
        assert {"id", "task", "entrance_lane", "exit_lane", "control_points", "points", "segment",
                "v_pass", "v_stop", "rho", "max_curvature", "exceeds_limit"} <= set(data)
        assert data["rho"] == pytest.approx(c.rho) and data["max_curvature"] == pytest.approx(c.max_curvature, abs=1e-4)
        assert len(data["control_points"]) == 6 and all(len(p) == 2 for p in data["control_points"])
        assert len(data["points"]) == len(c.points) and len(data["points"][0]) == 5
        assert len(data["segment"]) == len(data["v_pass"]) == len(data["v_stop"]) == len(c.points)


def test_errors() -> None:
    j = four_way_junction(n_lanes=2)
    no_left = four_way_junction(n_lanes=2)
    approach = no_left.default_approach()
    object.__setattr__(approach, "connections", tuple(c for c in approach.connections if c.turn != "left"))
    with pytest.raises(PlanningError, match="approach in0 has no left-turn connection; it allows: straight, right"):
        plan_candidates(no_left, "left")
    with pytest.raises(PlanningError, match="unknown task 'uturn2'"):
        plan_candidates(j, "uturn2")
    for rho in (0.0, 1.0, -0.2, 1.5):
        with pytest.raises(PlanningError, match="rho"):
            plan_candidates(j, "left", rho=rho)
    with pytest.raises(PlanningError, match="no approach 'nope'"):
        plan_candidates(j, "left", approach="nope")
    with pytest.raises(PlanningError, match="entrance_length_m"):
        plan_candidates(j, "left", entrance_length_m=0.0)
    with pytest.raises(PlanningError, match="not an entrance lane"):
        plan_candidates(j, "left", entrance_lane="out1_0")
    with pytest.raises(PlanningError, match=r"\(lane in0_0\) has no left-turn connection"):
        plan_candidates(j, "left", entrance_lane="in0_0")


def test_other_approaches_and_rho() -> None:
    j = four_way_junction(n_lanes=2)
    for a in j.approaches:
        assert len(plan_candidates(j, "left", approach=a.id)) == 2
    tight = plan_candidates(j, "left", rho=0.9)[0]
    loose = plan_candidates(j, "left", rho=0.1)[0]
    assert tight.length_m != pytest.approx(loose.length_m)
