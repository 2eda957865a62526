"""Pedestrians and cyclists stop rather than walk or ride into a standing ego: the geometry, the
standoff, and the rule in SUMO."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from crossroads.intersections import catalogue
from crossroads.sim.courtesy import (
    CAR_SPARE_M,
    CYCLIST_NEAR_M,
    CYCLIST_STANDOFF_S,
    Cars,
    Courtesy,
    LOOKAHEAD_MIN_M,
    PEDESTRIAN_STANDOFF_S,
    SIDE_FRONT_EXCLUDED_M,
    Movers,
    car_reach,
    cyclist_reach,
    driving_into,
    driving_into_side,
    following,
    moving_into,
    riding_into,
    sweeping_into,
    walking_into,
)
from crossroads.geometry import arc_lengths, footprint_points, placed_along
from crossroads.sim.look_ahead import WayAhead, comes_nearer
from crossroads.sim.sumo import SumoSession
from crossroads.sim.traffic import VTYPES_XML
from support import patched_episode

EGO = (0.0, 0.0, 0.0, 4.8, 2.0)  # x, y, heading (east), length, width


def _into(x: float, y: float, heading: float, speed: float) -> bool:
    return bool(walking_into(*EGO, np.array([x]), np.array([y]), np.array([heading]), np.array([speed]))[0])


def test_walking_at_the_cars_side_is_walking_into_it() -> None:
    assert _into(0.0, 2.0, -np.pi / 2, 1.3)  # 1 m from the side, walking toward it


def test_walking_away_past_or_far_is_not() -> None:
    assert not _into(0.0, 2.0, np.pi / 2, 1.3)  # walking away
    assert not _into(0.0, 3.0, 0.0, 1.3)  # walking past, 2 m from the side
    assert not _into(0.0, 5.0, -np.pi / 2, 1.3)  # walking toward it, 4 m out: more than a second


def test_already_touching_is_the_judges_business() -> None:
    assert not _into(2.0, 0.5, 0.0, 1.3)


def test_a_cyclist_looks_as_far_as_it_needs_to_stop() -> None:
    assert cyclist_reach(np.array([5.4]))[0] == pytest.approx(5.4 + 5.4**2 / 6.0)
    # riding east 0.3 m right of a car standing turned 17° to the right: into its side
    assert bool(riding_into(0.0, 0.0, -0.3, 4.8, 2.0, np.array([-6.0]), np.array([-1.6]), np.array([0.0]),
                            np.array([5.4]))[0])
    # the same car standing straight: it rides past
    assert not bool(riding_into(0.0, 0.0, 0.0, 4.8, 2.0, np.array([-6.0]), np.array([-1.6]), np.array([0.0]),
                                np.array([5.4]))[0])


def _driving(x: float, y: float, heading: float, speed: float, ego_heading: float = 0.0) -> bool:
    return bool(driving_into(0.0, 0.0, ego_heading, 4.8, 2.0, np.array([x]), np.array([y]), np.array([heading]),
                             np.array([speed]), np.array([4.5]), np.array([1.8]))[0])


def test_a_driver_looks_as_far_as_it_needs_to_stop() -> None:
    assert car_reach(np.array([10.0]))[0] == pytest.approx(10.0 + 100.0 / 9.0)


def test_a_car_heading_for_the_standing_egos_side_is_driving_into_it() -> None:
    # the ego stands across the way (heading north); a car 20 m to its west drives east at 10 m/s:
    # its bumper is 15.35 m from the ego's side, within its 21.1 m reach
    assert _driving(-20.0, 0.0, 0.0, 10.0, ego_heading=np.pi / 2)
    assert not _driving(-40.0, 0.0, 0.0, 10.0, ego_heading=np.pi / 2)  # beyond its reach
    assert _driving(-5.0, 0.0, 0.0, 0.0, ego_heading=np.pi / 2)  # standing: 1 m ahead of its bumper
    assert not _driving(-6.0, 0.0, 0.0, 0.0, ego_heading=np.pi / 2)


def test_a_car_passing_alongside_or_driving_away_is_not() -> None:
    assert not _driving(-15.0, 3.5, 0.0, 10.0)  # the next lane, 3.5 m from the ego's centre line
    assert not _driving(8.0, 0.0, 0.0, 10.0)  # ahead of the ego, driving away
    assert _driving(-15.0, 1.2, 0.0, 10.0)  # 1.2 m off the ego's line: its side would touch


def _arc(cx: float, cy: float, radius: float, start_deg: float, end_deg: float) -> np.ndarray:
    """A way along a circle round (cx, cy), from ``start_deg`` to ``end_deg`` (1° steps)."""
    a = np.radians(np.linspace(start_deg, end_deg, int(abs(end_deg - start_deg)) + 1))
    return np.column_stack([cx + radius * np.cos(a), cy + radius * np.sin(a)])


def test_a_car_turning_into_the_standing_ego_sweeps_into_it_where_its_straight_way_ahead_misses() -> None:
    # a right turn of radius 8 m round (0, 8): the car's front at (0, 0) heading east, turning
    # north; the ego stands beside the turn, its centre at (6.5, 4.0), heading north
    way = _arc(0.0, 8.0, 8.0, -90.0, 0.0)
    ego = (6.5, 4.0, np.pi / 2, 4.8, 2.0)
    assert sweeping_into(*ego, way, 4.5, 1.8, reach=6.0)
    car_centre = (-2.25, 0.0)  # the straight way ahead, east along y = 0, passes below the ego
    assert not driving_into(*ego, np.array([car_centre[0]]), np.array([car_centre[1]]), np.array([0.0]),
                            np.array([3.0]), np.array([4.5]), np.array([1.8]))[0]
    assert not sweeping_into(*ego, way, 4.5, 1.8, reach=1.0)  # not within a metre
    away = _arc(0.0, -8.0, 8.0, 90.0, 0.0)  # the same car turning right, the other way
    assert not sweeping_into(*ego, away, 4.5, 1.8, reach=6.0)
    # the ego already beside its front, within the spare: turning on brings it further in
    beside = (1.0, 1.5, 0.0, 4.8, 2.0)
    assert sweeping_into(*beside, way, 4.5, 1.8, reach=6.0)
    # a metre on along a longer way: the same as the way cut there
    longer = _arc(0.0, 8.0, 8.0, -97.2, 0.0)  # 1 m more of the circle before the front
    assert sweeping_into(*ego, longer, 4.5, 1.8, reach=6.0, start_m=1.005)
    assert not sweeping_into(*ego, longer, 4.5, 1.8, reach=1.0, start_m=1.005)


def test_cars_inside_the_junction_held_when_their_lane_bends_into_the_standing_ego() -> None:
    rule, session = Courtesy(), _Recorder()
    nobody = Movers(*(np.array([]) for _ in range(5)))
    cars = _cars(("turning", -2.25, 0.0, 0.0, 5.0))  # looks 7.8 m ahead
    ego = (6.5, 4.0, np.pi / 2, 0.0, 4.8, 2.0)
    rule.update(session, nobody, nobody, ego, cars)  # type: ignore[arg-type]
    assert not rule.held_cars  # its straight way ahead passes the ego
    way = _arc(0.0, 8.0, 8.0, -90.0, 0.0)
    rule.update(session, nobody, nobody, ego, cars, {"turning": WayAhead(way, arc_lengths(way), 0.0)})  # type: ignore[arg-type]
    assert rule.held_cars == {"turning"}


def _cars(*rows: tuple[str, float, float, float, float]) -> Cars:
    ids, x, y, heading, speed = (np.array(c) for c in zip(*rows, strict=True))
    return Cars(ids, x.astype(float), y.astype(float), heading.astype(float), speed.astype(float),
                np.full(len(rows), 4.5), np.full(len(rows), 1.8))


def test_cars_held_while_the_ego_stands_and_released_when_it_drives() -> None:
    rule, session = Courtesy(), _Recorder()
    nobody = Movers(*(np.array([]) for _ in range(5)))
    cars = _cars(("behind", -15.0, 0.0, 0.0, 8.0), ("alongside", -15.0, 3.5, 0.0, 8.0))
    for _ in range(2):
        rule.update(session, nobody, nobody, (0.0, 0.0, 0.0, 0.0, 4.8, 2.0), cars)  # type: ignore[arg-type]
    assert session.calls == [("hold", "behind")] and rule.held_cars == {"behind"}
    rule.update(session, nobody, nobody, (30.0, 0.0, 0.0, 3.0, 4.8, 2.0), cars)  # type: ignore[arg-type]
    assert session.calls == [("hold", "behind"), ("release", "behind")] and not rule.held_cars


class _Recorder:
    def __init__(self) -> None:
        self.calls: list[tuple[str, str]] = []
        self.time_s = 0.0

    def hold_vehicle(self, vid: str, holder: str) -> None:
        assert holder == "courtesy"
        self.calls.append(("hold", vid))

    def release_vehicle(self, vid: str, holder: str) -> None:
        assert holder == "courtesy"
        self.calls.append(("release", vid))

    def vehicle_lane(self, vid: str) -> str:
        return ":C_20_0"

    def person_lane(self, pid: str) -> str:
        return ":C_c0_0"

    def remove(self, vid: str) -> None:
        self.calls.append(("remove", vid))

    def hold_person(self, pid: str) -> None:
        self.calls.append(("hold", pid))

    def release_person(self, pid: str) -> None:
        self.calls.append(("release", pid))


def _one(pid: str, y: float, speed: float) -> Movers:
    return Movers(np.array([pid]), np.array([0.0]), np.array([y]), np.array([-np.pi / 2]), np.array([speed]))


NOBODY = Movers(np.array([]), np.array([]), np.array([]), np.array([]), np.array([]))


def _update(rule: Courtesy, session: _Recorder, ego_speed: float, *, cyclist: bool = False, ego_x: float = 0.0,
            mover_speed: float = 1.3) -> list:
    mover = _one("b" if cyclist else "p", 2.0, mover_speed)
    return rule.update(session, NOBODY if cyclist else mover, mover if cyclist else NOBODY,  # type: ignore[arg-type]
                       (ego_x, 0.0, 0.0, ego_speed, 4.8, 2.0))


@pytest.mark.parametrize("cyclist", [False, True])
def test_held_while_the_ego_stands_and_released_once_it_has_driven_on(cyclist: bool) -> None:
    rule, session = Courtesy(), _Recorder()
    who = "b" if cyclist else "p"
    _update(rule, session, 0.0, cyclist=cyclist)
    _update(rule, session, 0.0, cyclist=cyclist)  # still held: no second call
    assert session.calls == [("hold", who)]
    assert rule.may_act(5.0)  # someone is held: the rule must look even at speed
    # the ego pulls away, its side still across the held one's way (standing now: 1 m ahead)
    _update(rule, session, 1.0, cyclist=cyclist, ego_x=1.0, mover_speed=0.0)
    assert session.calls == [("hold", who)]
    _update(rule, session, 5.0, cyclist=cyclist, ego_x=6.0, mover_speed=0.0)  # past it
    assert session.calls == [("hold", who), ("release", who)]
    assert not rule.held_pedestrians and not rule.held_cyclists and not rule.may_act(5.0)


def test_a_moving_ego_holds_no_one_in_its_way_ahead() -> None:
    """In front of a moving ego a pedestrian or cyclist is in its way: the ego must stop for it."""
    for cyclist in (False, True):
        rule, session = Courtesy(), _Recorder()
        _update(rule, session, 3.0, cyclist=cyclist, ego_x=-2.5)  # crossing 0.1 m ahead of its bumper
        assert session.calls == [] and not rule.held_pedestrians and not rule.held_cyclists
        _update(rule, session, 0.0, cyclist=cyclist, ego_x=-2.5)  # had it stood, they would have stopped
        assert session.calls == [("hold", "b" if cyclist else "p")]


def test_a_pedestrian_about_to_walk_into_a_moving_egos_side_stops() -> None:
    rule, session = Courtesy(), _Recorder()
    _update(rule, session, 3.0)  # walking at the middle of its side
    assert session.calls == [("hold", "p")]
    rule, session = Courtesy(), _Recorder()
    rule.watch_sides(session, _one("p", 2.0, 1.3), (0.0, 0.0, 0.0, 3.0, 4.8, 2.0))  # type: ignore[arg-type]
    assert session.calls == [("hold", "p")] and rule.held_pedestrians == {"p"}
    rule, session = Courtesy(), _Recorder()
    _update(rule, session, 3.0, cyclist=True)  # a cyclist riding into its side: the ego's turn across it
    assert session.calls == []


def test_a_cyclist_following_a_moving_ego_into_its_rear_quarter_stops() -> None:
    """f_irregular_wide's right turn, seed 1120857481 (the rule controller, base seed 20261206): a
    cyclist behind the ego, heading 30° off its way, rides into its rear quarter as it sets off."""
    rule, session = Courtesy(), _Recorder()
    behind = Movers(np.array(["b"]), np.array([-4.1]), np.array([-2.1]), np.array([np.radians(30.0)]),
                    np.array([1.4]))
    rule.watch_sides(session, NOBODY, (0.0, 0.0, 0.0, 0.7, 4.8, 2.0), behind)  # type: ignore[arg-type]
    assert session.calls == [("hold", "b")] and set(rule.held_cyclists) == {"b"}


def test_a_cyclist_seen_beyond_its_braking_reach_stops_short_of_the_standing_ego() -> None:
    """f_irregular_wide's right turn, seed 1114790774: a cyclist at 5.4 m/s making for the standing
    ego from 11 m away must be held now; within 8 m of the ego's centre it could no longer stop."""
    assert cyclist_reach(np.array(5.4)) + 2.4 < CYCLIST_NEAR_M
    rule, session = Courtesy(), _Recorder()
    far = Movers(np.array(["b"]), np.array([-11.0]), np.array([0.0]), np.array([0.0]), np.array([5.4]))
    rule.update(session, NOBODY, far, (0.0, 0.0, 0.0, 0.0, 4.8, 2.0))  # type: ignore[arg-type]
    assert session.calls == [("hold", "b")]


def test_a_cyclist_held_too_long_goes_round_the_car() -> None:
    rule, session = Courtesy(), _Recorder()
    assert _update(rule, session, 0.0, cyclist=True) == []
    session.time_s = CYCLIST_STANDOFF_S - 0.5
    assert _update(rule, session, 0.0, cyclist=True) == []
    session.time_s = CYCLIST_STANDOFF_S
    (removal,) = _update(rule, session, 0.0, cyclist=True)
    assert removal.participant == "b" and removal.stood_s == pytest.approx(CYCLIST_STANDOFF_S)
    assert session.calls == [("hold", "b"), ("remove", "b")] and not rule.held_cyclists
    assert removal.to_event(3.0)["event"] == "gridlock_removed"


# 0.45 m ahead of the bumper, walking across its front and a little towards it (as in c_three_lane's
# left turn, seed 1416578486 of base seed 20261206)
_IN_FRONT = Movers(np.array(["f"]), np.array([2.85]), np.array([0.5]), np.array([-np.pi / 2 - 0.2]), np.array([1.3]))


def test_a_pedestrian_held_in_front_of_the_standing_ego_goes_round_it_and_one_beside_it_waits() -> None:
    rule, session = Courtesy(), _Recorder()
    ego = (0.0, 0.0, 0.0, 0.0, 4.8, 2.0)  # its front bumper at x = 2.4, its sides at y = ±1
    front = _IN_FRONT
    beside = _one("s", 2.0, 1.3)  # walking into the middle of its side
    both = Movers(*(np.concatenate([a, b]) for a, b in zip(front, beside, strict=True)))
    assert rule.update(session, both, NOBODY, ego) == []  # type: ignore[arg-type]
    assert rule.held_pedestrians == {"f", "s"} and set(rule.held_in_front) == {"f"}
    session.time_s = PEDESTRIAN_STANDOFF_S - 0.5
    assert rule.update(session, both, NOBODY, ego) == []  # type: ignore[arg-type]
    session.time_s = PEDESTRIAN_STANDOFF_S
    (removal,) = rule.update(session, both, NOBODY, ego)  # type: ignore[arg-type]
    assert removal.participant == "f" and removal.lane == ":C_c0_0"
    assert ("remove", "f") in session.calls and rule.held_pedestrians == {"s"} and not rule.held_in_front


def test_the_standoff_in_front_counts_only_while_the_ego_stands() -> None:
    rule, session = Courtesy(), _Recorder()
    front = _IN_FRONT
    rule.update(session, front, NOBODY, (0.0, 0.0, 0.0, 0.0, 4.8, 2.0))  # type: ignore[arg-type]
    session.time_s = 5.0
    rule.watch_sides(session, NOBODY, (0.0, 0.0, 0.0, 2.0, 4.8, 2.0))  # type: ignore[arg-type]  # it moved
    session.time_s = PEDESTRIAN_STANDOFF_S
    assert rule.update(session, front, NOBODY, (0.0, 0.0, 0.0, 0.0, 4.8, 2.0)) == []  # type: ignore[arg-type]
    assert rule.held_in_front == {"f": PEDESTRIAN_STANDOFF_S}


def test_off_means_off() -> None:
    rule, session = Courtesy(enabled=False), _Recorder()
    _update(rule, session, 0.0)
    assert session.calls == [] and not rule.may_act(0.0)


@pytest.fixture(scope="module")
def net() -> Path:
    return catalogue.build("c_three_lane")


def test_a_held_pedestrian_stands_in_sumo_and_walks_on_when_released(net: Path, tmp_path: Path) -> None:
    routes = tmp_path / "p.rou.xml"
    routes.write_text(f'<routes>\n{VTYPES_XML}    <person id="walker" type="pedestrian" depart="0">\n'
                      '        <walk from="south_in" to="east_out"/>\n    </person>\n</routes>\n')
    with SumoSession().start(net, [routes], seed=1) as session:
        for _ in range(30):
            session.step()
        session.hold_person("walker")
        session.step()
        first = session.snapshot()
        for _ in range(20):
            session.step()
        held = session.snapshot()
        row0, row1 = list(first.ids).index("walker"), list(held.ids).index("walker")
        assert np.hypot(held.x[row1] - first.x[row0], held.y[row1] - first.y[row0]) < 0.05
        session.release_person("walker")
        for _ in range(20):
            session.step()
        walked = session.snapshot()
        row2 = list(walked.ids).index("walker")
        assert np.hypot(walked.x[row2] - held.x[row1], walked.y[row2] - held.y[row1]) > 1.0


def test_after_a_cyclist_goes_round_the_car_the_observation_reads_no_one_gone() -> None:
    # SUMO's driver stands in its right turn on e_irregular_oblique while a cyclist is held behind
    # it for 8 s (base seed 20261206's run 466267842): the cyclist is taken out mid-step, and the
    # step's observation must not name it (reading its lane would fail in SUMO)
    from crossroads.evaluation.sumo_driver import SumoDriverPolicy
    from crossroads.scenario.spec import load_scenario, to_world_config
    from crossroads.sim.world import World

    spec = load_scenario(Path(__file__).parents[2] / "scenarios/nominal/e_irregular_oblique-right.yaml")
    with World(to_world_config(spec)) as world:
        obs = world.reset(466267842, sumo_driver=SumoDriverPolicy().driver)
        outcome = None
        while outcome is None:
            obs, outcome = world.step(None)
            world.truth.participants.lane_id  # noqa: B018 - reads every participant's lane in SUMO
        removed = [e for e in world.events if e["event"] == "gridlock_removed" and e["value"]["id"].startswith("bike")]
    assert removed and outcome.kind == "passed"


@pytest.mark.slow
def test_a_pedestrian_held_beside_the_ego_does_not_walk_into_it_as_it_pulls_away() -> None:
    """The nominal left turn of e_irregular_oblique, run 1311414304 of benchmarks/world_flow.py's
    base seed, SUMO's driver: the car ahead of the standing ego is taken out by the gridlock breaker
    and the ego starts; a pedestrian held 0.9 m from its front corner, released the moment the ego
    moved, walked into it. Kept held until the ego has passed, it does not. ("off": the rule before,
    which held no one for a moving ego.) The world without the rules that came after and change
    this run's traffic (``let_out``, ``junction_lane_changes``). Fresh processes, as ``crossroads
    run`` (SUMO's result can depend on what the process ran before)."""
    # the scene as it was found: before drivers let those caught inside out, and changed lanes inside
    scene = {"let_out": False, "junction_lane_changes": True}
    # the rule before: those held go the moment the ego moves, and it holds no one new
    before = ("crossroads.sim.courtesy:_only=lambda movers, ids: type(movers)(*(c[:0] for c in movers))",
              "crossroads.sim.courtesy:walking_into_side=lambda *args: walking_into(*args) & False")
    outcomes = {mode: patched_episode("e_irregular_oblique-left", "sumo", 1311414304,
                                      *(before if mode == "off" else ()), world=scene)
                for mode in ("off", "on")}
    assert outcomes["off"][:2] == ["collision", "hit pedestrian ped4"], outcomes
    assert outcomes["on"][0] != "collision", outcomes


def test_a_car_standing_within_the_spare_may_not_turn_further_in() -> None:
    # a_single_lane's left turn, seed 1101115134 (base seed 20261206): a left-turner on its internal
    # lane stood 0.07 m from the standing ego's corner for a minute, then drove off into it. Its
    # way (the lane's points round its front), the ego's pose, the car 4.5 m x 1.8 m, 5.088 m along:
    way = np.array([(-3.5, 5.94), (-3.8, 5.54), (-4.11, 5.16), (-4.44, 4.79), (-4.79, 4.44), (-5.16, 4.11),
                    (-5.54, 3.8), (-5.94, 3.5), (-6.35, 3.23), (-6.77, 2.98), (-7.21, 2.75), (-7.5, 2.61),
                    (-7.5, 2.61), (-7.66, 2.54), (-8.12, 2.36), (-8.58, 2.2), (-9.06, 2.06)])
    ego = (-5.248, -0.078, 2.64, 4.8, 2.0)
    assert sweeping_into(*ego, way, 4.5, 1.8, reach=car_reach(np.array([0.0]))[0], start_m=5.088)
    # placed as SUMO placed it: centre (-5.586, 4.089), heading -2.468 rad
    x, y, heading = placed_along(way, arc_lengths(way), np.array([5.088]), 4.5)
    assert (x[0], y[0], heading[0]) == pytest.approx((-5.586, 4.089, -2.468), abs=0.01)


def test_a_car_alongside_within_the_spare_driving_past_is_not_held() -> None:
    # a straight way along y = 0 past the ego standing 1.9 m to its side (0.1 m within the spare)
    way = np.column_stack([np.linspace(-10.0, 10.0, 21), np.zeros(21)])
    ego = (0.0, 1.9, 0.0, 4.8, 2.0)
    assert not sweeping_into(*ego, way, 4.5, 1.8, reach=6.0, start_m=10.0)  # alongside: stays as near
    assert sweeping_into(*ego, way, 4.5, 1.8, reach=6.0, start_m=4.0)  # behind: would come alongside


def test_a_car_behind_the_ego_heading_its_way_follows_it() -> None:
    ego = (0.0, 0.0, 0.0, 4.8, 2.0, 5.0)  # heading east, moving
    xs, ys = np.array([-7.0, -7.0, 7.0, -7.0, -20.0]), np.array([0.0, 1.5, 0.0, 0.0, 0.0])
    headings = np.array([0.0, 0.5, 0.0, np.pi, 0.0])
    # behind in its lane; behind, merging; ahead; behind, heading the other way; too far behind
    assert following(ego, xs, ys, headings).tolist() == [True, True, False, False, False]


def test_a_moving_ego_holds_the_cars_following_it_or_heading_for_its_side() -> None:
    session = _Recorder()
    rule = Courtesy()
    ego = (0.0, 0.0, 0.0, 3.0, 4.8, 2.0)  # moving east at 3 m/s
    # 6 m behind the ego's centre at 6 m/s: its bumper 1.35 m from the ego's rear, 5.6 m reach
    behind = Cars(np.array(["c"]), np.array([-6.0]), np.array([0.0]), np.array([0.0]), np.array([6.0]),
                  np.array([4.5]), np.array([1.8]))
    crossing = Cars(np.array(["x"]), np.array([5.0]), np.array([-6.0]), np.array([np.pi / 2]), np.array([6.0]),
                    np.array([4.5]), np.array([1.8]))
    rule.update(session, NOBODY, NOBODY, ego, behind)  # type: ignore[arg-type]
    assert rule.held_cars == {"c"}
    rule = Courtesy()
    rule.update(session, NOBODY, NOBODY, ego, crossing)  # type: ignore[arg-type]
    assert rule.held_cars == set()  # one ahead of the moving ego's bumper: the ego's to stop for
    # one heading for the moving ego's side (its bumper 4.75 m from it, 9.6 m reach) brakes for it
    side = Cars(np.array(["s"]), np.array([0.0]), np.array([-8.0]), np.array([np.pi / 2]), np.array([6.0]),
                np.array([4.5]), np.array([1.8]))
    assert rule.may_act(3.0, side, ego)
    rule.update(session, NOBODY, NOBODY, ego, side)  # type: ignore[arg-type]
    assert rule.held_cars == {"s"}
    assert not Courtesy().may_act(3.0, crossing, ego)


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "cyclist"), [(1114790774, "bike23"), (1120857481, "bike24")])
def test_cyclists_stop_short_of_the_rule_controllers_right_turn(seed: int, cyclist: str) -> None:
    """f_irregular_wide's right turn with the rule controller, runs of benchmarks/world_flow.py's base
    seed (module docstring): with cyclists looked at only within 8 m and none held for a moving ego's
    side they rode into it; now they stop. Fresh processes, as ``crossroads run``."""
    def outcome(*patches: str) -> list:
        return patched_episode("f_irregular_wide-right", "rule", seed, *patches)

    before = outcome("crossroads.sim.courtesy:CYCLIST_NEAR_M=8.0",
                     "crossroads.sim.courtesy:riding_into_side=lambda *a: np.zeros(len(a[5]), dtype=bool)")
    assert before[:2] == ["collision", f"hit cyclist {cyclist}"], before
    assert outcome()[0] == "passed"


# --- the fast paths answer as the plain array formulation ---------------------------------------

def _plain_moving_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                       x: np.ndarray, y: np.ndarray, heading: np.ndarray, reach: np.ndarray,
                       margin_m: float | np.ndarray, front_m: float | None = None) -> np.ndarray:
    """``moving_into`` as arrays of (movers, samples), every mover's every sample computed."""
    reach = np.maximum(np.asarray(reach, dtype=float), LOOKAHEAD_MIN_M)
    c, s = math.cos(ego_heading), math.sin(ego_heading)
    margin = np.broadcast_to(np.asarray(margin_m, dtype=float), reach.shape)[:, None]
    half_l, half_w = ego_length / 2.0 + margin, ego_width / 2.0 + margin
    samples = np.linspace(0.0, 1.0, 8)
    dx = (x[:, None] + np.cos(heading)[:, None] * reach[:, None] * samples) - ego_x
    dy = (y[:, None] + np.sin(heading)[:, None] * reach[:, None] * samples) - ego_y
    along, across = dx * c + dy * s, -dx * s + dy * c
    ahead = half_l if front_m is None else np.minimum(half_l, front_m)
    inside = (along >= -half_l) & (along <= ahead) & (np.abs(across) <= half_w)
    return comes_nearer(inside, np.maximum(np.abs(along) - half_l, np.abs(across) - half_w))


def _plain_sweeping_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                         way: np.ndarray, length: float, width: float, reach: float, start_m: float) -> bool:
    """``sweeping_into`` with every placement computed, no car skipped as far."""
    cum = arc_lengths(way)
    s = start_m + np.linspace(0.0, max(min(max(reach, LOOKAHEAD_MIN_M), float(cum[-1]) - start_m), 0.0), 8)
    cx, cy, headings = placed_along(way, cum, s, length)
    px, py = footprint_points(cx, cy, headings, np.full(len(s), length), np.full(len(s), width))
    c, si = math.cos(ego_heading), math.sin(ego_heading)
    dx, dy = px - ego_x, py - ego_y
    along, across = dx * c + dy * si, -dx * si + dy * c
    depth = np.maximum(np.abs(along) - (0.5 * ego_length + CAR_SPARE_M),
                       np.abs(across) - (0.5 * ego_width + CAR_SPARE_M)).min(axis=1)
    return bool(comes_nearer(depth <= 0.0, depth))


@pytest.mark.parametrize("front_m", [None, 1.9])
def test_moving_into_answers_as_the_plain_formulation(front_m: float | None) -> None:
    rng = np.random.default_rng(20261207)
    hits = 0
    for _ in range(400):
        n = int(rng.integers(1, 12))
        ego = (float(rng.uniform(-50, 50)), float(rng.uniform(-50, 50)), float(rng.uniform(-math.pi, math.pi)),
               float(rng.uniform(3.5, 5.5)), float(rng.uniform(1.6, 2.2)))
        x, y = ego[0] + rng.uniform(-12, 12, n), ego[1] + rng.uniform(-12, 12, n)
        heading, reach = rng.uniform(-math.pi, math.pi, n), rng.uniform(0.0, 14.0, n)
        margin = rng.uniform(0.2, 1.2, n) if rng.random() < 0.5 else float(rng.uniform(0.2, 1.2))
        fast = moving_into(*ego, x, y, heading, reach, margin, front_m)
        np.testing.assert_array_equal(fast, _plain_moving_into(*ego, x, y, heading, reach, margin, front_m))
        hits += int(fast.sum())
    assert hits > 100  # the draws come into the ego often enough to tell


def test_sweeping_into_answers_as_the_plain_formulation() -> None:
    rng = np.random.default_rng(20261208)
    answers = []
    for _ in range(300):
        cx, cy = rng.uniform(-15, 15, 2)
        way = _arc(float(cx), float(cy), float(rng.uniform(6, 25)), float(rng.uniform(0, 360)),
                   float(rng.uniform(0, 360)) + float(rng.choice([-90.0, 90.0])))
        near = way[int(rng.integers(len(way)))] + rng.uniform(-4, 4, 2)  # the ego near the way or on it
        ego = (float(near[0]), float(near[1]), float(rng.uniform(-math.pi, math.pi)), 4.8, 2.0)
        length, width, reach = float(rng.uniform(3.5, 6)), float(rng.uniform(1.6, 2.2)), float(rng.uniform(0, 20))
        start = float(rng.uniform(0, arc_lengths(way)[-1]))
        fast = sweeping_into(*ego, way, length, width, reach, start_m=start)
        assert fast == _plain_sweeping_into(*ego, way, length, width, reach, start)
        answers.append(fast)
    assert 20 < sum(answers) < 280  # both answers drawn


@pytest.mark.parametrize("side", [False, True])
def test_driving_into_answers_as_the_plain_formulation(side: bool) -> None:
    rng = np.random.default_rng(20261209)
    hits = 0
    for _ in range(400):
        n = int(rng.integers(1, 16))
        ego = (float(rng.uniform(-50, 50)), float(rng.uniform(-50, 50)), float(rng.uniform(-math.pi, math.pi)), 4.8, 2.0)
        x, y = ego[0] + rng.uniform(-25, 25, n), ego[1] + rng.uniform(-25, 25, n)
        heading, speed = rng.uniform(-math.pi, math.pi, n), rng.uniform(0.0, 14.0, n) * (rng.random(n) < 0.7)
        length, width = rng.uniform(3.5, 12.0, n), rng.uniform(1.6, 2.5, n)
        test = driving_into_side if side else driving_into
        fast = test(*ego, x, y, heading, speed, length, width)
        half = 0.5 * length
        plain = _plain_moving_into(*ego, x + half * np.cos(heading), y + half * np.sin(heading), heading,
                                   car_reach(speed), 0.5 * width + CAR_SPARE_M,
                                   ego[3] / 2.0 - SIDE_FRONT_EXCLUDED_M if side else None)
        np.testing.assert_array_equal(fast, plain)
        hits += int(fast.sum())
    assert hits > 50
