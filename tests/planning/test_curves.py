"""Which ρ draws a candidate's curve, where X1 and X4 move, and which curves are refused."""

from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import LineString

from crossroads.constants import RHO_BEZIER
from crossroads.geometry import (
    bezier_control_points_closed_form,
    cubic_bezier_derivatives,
    heading_curvature_from_derivatives,
    point_at,
)
from crossroads.network.road import Lane
from crossroads.planning import PlanningError, build_candidate, plan_candidates, plan_task
from crossroads.planning.curves import (
    MAX_CURVATURE,
    PAPER_RHO_MAX_CURVATURE,
    RHO_GRID,
    max_curvatures,
    rho_preferences,
)
from crossroads.planning.drivable import ROAD_MARGIN_M, footprint_corners
from crossroads.planning.routes import ENDPOINT_SHIFT_MAX_M
from planning.factories import four_way_junction


def lane(lane_id: str, *points: tuple[float, float], width: float = 3.5) -> Lane:
    return Lane(lane_id, lane_id.rsplit("_", 1)[0], 0, width, 13.9, np.array(points, float),
                frozenset({"passenger"}))


def test_the_limit_is_the_ego_at_full_lock() -> None:
    assert MAX_CURVATURE == pytest.approx(math.tan(0.4) / 2.65)
    assert 1.0 / MAX_CURVATURE == pytest.approx(6.27, abs=0.01)


@pytest.mark.parametrize("rho", [0.1, 0.45, RHO_BEZIER, 0.9])
def test_max_curvature_is_the_curve_s_own(rho: float) -> None:
    """The vectorised figure equals the Bezier's curvature from its derivatives (finely sampled)."""
    x1, x4, th_in, th_out = np.array([0.0, 0.0]), np.array([12.0, 9.0]), math.pi / 2, 0.2
    x2, x3 = bezier_control_points_closed_form(x1, x4, th_in, th_out, rho)
    t = np.linspace(0.0, 1.0, 20001)
    _, kappa = heading_curvature_from_derivatives(*cubic_bezier_derivatives(np.vstack([x1, x2, x3, x4]), t))
    got = max_curvatures(x1, x4, th_in, th_out, np.array([rho]))[0]
    assert got == pytest.approx(np.abs(kappa).max(), rel=2e-3)


def test_the_paper_s_rho_first_where_it_bends_gently() -> None:
    wide = rho_preferences(np.zeros(2), np.array([-30.0, 30.0]), math.pi / 2, math.pi)  # a wide left
    assert wide[0].rho == RHO_BEZIER and wide[0].max_curvature <= PAPER_RHO_MAX_CURVATURE
    assert [c.max_curvature for c in wide[1:]] == sorted(c.max_curvature for c in wide[1:])
    tight = rho_preferences(np.zeros(2), np.array([9.0, 12.0]), math.pi / 2, 0.0)  # into an inner lane
    assert tight[0].rho != RHO_BEZIER and len(tight) == len(RHO_GRID)
    paper = max_curvatures(np.zeros(2), np.array([9.0, 12.0]), math.pi / 2, 0.0, np.array([RHO_BEZIER]))[0]
    assert paper > MAX_CURVATURE > tight[0].max_curvature  # ρ alone brings this one within the limit


def test_x1_and_x4_move_where_no_rho_is_enough() -> None:
    """A right turn whose lanes end and begin 3.5 m apart: no ρ bends it gently enough, moving X1
    back and X4 on does; the stop line and the exit lane's start stay where they are."""
    entrance = lane("in_0", (0.0, -60.0), (0.0, 0.0))
    exit_ = lane("out_0", (3.5, 3.5), (80.0, 3.5))
    assert min(c.max_curvature for c in rho_preferences(entrance.end, exit_.start, math.pi / 2, 0.0)) > MAX_CURVATURE
    c = build_candidate("right-0", "right", "in", entrance, exit_)
    assert c.max_curvature <= MAX_CURVATURE and not c.exceeds_limit
    assert 0.0 < c.x1_shift_m <= ENDPOINT_SHIFT_MAX_M and 0.0 < c.x4_shift_m <= ENDPOINT_SHIFT_MAX_M
    np.testing.assert_allclose(c.control_points[1], point_at(entrance.centerline, 60.0 - c.x1_shift_m))
    np.testing.assert_allclose(c.control_points[4], point_at(exit_.centerline, c.x4_shift_m))
    # the speed profile's stop line and exit are the lanes' end and start, on the path
    assert c.s_stop_line == pytest.approx(c.project(*entrance.end).s_m, abs=1e-6)
    assert c.s_exit == pytest.approx(c.project(*exit_.start).s_m, abs=1e-6)
    assert c.s_stop_line > c.s[np.argmax(c.segment == "curve")]  # the curve begins before the line
    assert np.all(c.v_stop[c.s >= c.s_stop_line - 1e-9][: 3] == 0.0)
    # the paper's construction keeps the lane ends, and bends far tighter
    paper = build_candidate("right-0", "right", "in", entrance, exit_, rho=RHO_BEZIER)
    assert (paper.x1_shift_m, paper.x4_shift_m) == (0.0, 0.0) and paper.exceeds_limit


def test_the_entrance_route_runs_over_the_lead_in() -> None:
    """A 20 m entrance lane with 60 m of road before it: the entrance route takes its 50 m."""
    entrance = lane("in_0", (0.0, -20.0), (0.0, 0.0))
    exit_ = lane("out_0", (0.0, 15.0), (0.0, 80.0))
    lead_in = np.array([[0.0, -80.0], [0.0, -20.0], [0.0, 0.0]])
    c = build_candidate("straight-0", "straight", "in", entrance, exit_, lead_in=lead_in)
    np.testing.assert_allclose(c.control_points[0], [0.0, -50.0])
    assert c.s_stop_line == pytest.approx(50.0)
    short = build_candidate("straight-0", "straight", "in", entrance, exit_)
    np.testing.assert_allclose(short.control_points[0], [0.0, -20.0])


def test_a_curve_off_the_road_is_refused_with_its_reason() -> None:
    """Without the junction's area (only its lanes) no curve keeps the footprint on the road: each
    movement is refused, and planning the task fails with one line naming the first reason."""
    j = four_way_junction(n_lanes=2)
    lanes_only = j.drivable_area.difference(j.polygon)
    object.__setattr__(j, "drivable_area", lanes_only)
    plan = plan_task(j, "left")
    assert not plan.candidates and len(plan.refused) == 2
    assert all("footprint leaves the drivable area by" in r.reason for r in plan.refused)
    assert plan.warnings[0].startswith("no candidate into out3_0 (from in0_1): ")
    with pytest.raises(PlanningError, match=r"^no drivable left-turn path: .*leaves the drivable area.*\(and 1 more"):
        plan_candidates(j, "left")


def test_a_curve_over_another_approach_s_entrance_is_refused() -> None:
    """The opposite approach's entrance lanes drawn on across the junction (as a joined pair of
    SUMO nodes can have them): the left turns would cross them and are refused; the right turn,
    which stays clear of them, is offered."""
    j = four_way_junction(n_lanes=2)
    opposite = j.approach("in2")
    for ln in opposite.entrance_lanes:
        far = ln.end + 30.0 * (ln.end - ln.start) / np.linalg.norm(ln.end - ln.start)
        object.__setattr__(ln, "centerline", np.vstack([ln.start, far]))
    plan = plan_task(j, "left")
    assert not plan.candidates
    assert all("runs over the entrance lanes of approach 'in2'" in r.reason for r in plan.refused)
    assert plan_candidates(j, "right")


def test_footprint_corners() -> None:
    xs, ys = footprint_corners(np.array([[10.0, 5.0]]), np.array([math.pi / 2]))
    assert sorted(zip(np.round(xs, 9), np.round(ys, 9))) == [(9.0, 2.6), (9.0, 7.4), (11.0, 2.6), (11.0, 7.4)]
    assert ROAD_MARGIN_M == 0.5  # the world judge's overhang (sim.world.OFF_ROAD_TOLERANCE_M)


def test_every_candidate_keeps_its_footprint_on_the_road() -> None:
    j = four_way_junction(n_lanes=3, leg_angles_deg=(-100.0, 10.0, 75.0, 200.0))
    road = j.drivable_area.buffer(ROAD_MARGIN_M + 1e-6)
    for task in ("left", "straight", "right"):
        for c in plan_candidates(j, task):
            curve = c.segment == "curve"
            xs, ys = footprint_corners(c.points[curve], c.heading[curve])
            assert all(road.contains(LineString([(x, y), (x, y + 1e-9)])) for x, y in zip(xs, ys)), c.id


def test_a_turn_no_car_can_make_is_refused_with_how_tight_it_is() -> None:
    """A right turn between lanes 1.5 m apart whose short lanes leave nothing to move X1 and X4
    along: no ρ gets it within the limit, so it is refused, saying how much the least bent curve
    bends; with the paper's fixed ρ it is drawn as asked, and the plan warns of it."""
    entrance = lane("in_0", (0.0, -2.0), (0.0, 0.0))
    exit_ = lane("out_0", (1.5, 1.5), (3.5, 1.5))
    with pytest.raises(PlanningError, match=r"in_0 -> out_0: no curve a car can drive: the least bent one "
                                            r"that keeps to the road bends 0\.\d+ 1/m \(X1 back 0 m, X4 on 0 m\)"):
        build_candidate("right-0", "right", "in", entrance, exit_)
    forced = build_candidate("right-0", "right", "in", entrance, exit_, rho=RHO_BEZIER)
    assert forced.exceeds_limit and forced.to_json()["exceeds_limit"] is True
    plan = plan_task(four_way_junction(n_lanes=1), "right", rho=RHO_BEZIER)
    assert plan.candidates[0].exceeds_limit
    assert plan.warnings == [f"candidate right-0 (in0_0 -> out1_0) bends up to {plan.candidates[0].max_curvature:.3f} "
                             "1/m, tighter than the ego can steer (0.160 1/m): drawn with the fixed rho 0.6"]
    assert plan_task(four_way_junction(n_lanes=1), "right").warnings == []
