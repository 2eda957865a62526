"""The world's gridlock breaker in real SUMO: who stands inside the junction too long is removed,
who waits at a red stop line is not, and a junction held by a stalled vehicle flows again."""

from __future__ import annotations

from pathlib import Path

import pytest

from crossroads.intersections import catalogue
from crossroads.network.junction import read_junction
from crossroads.sim.gridlock import GridlockBreaker, internal_lane_prefixes
from crossroads.sim.sumo import SumoSession
from crossroads.sim.traffic import VTYPES_XML


@pytest.fixture(scope="module")
def net() -> Path:
    return catalogue.build("c_three_lane")


def _routes(path: Path, trips: list[tuple[str, float, str, str, int]]) -> Path:
    """A route file of car trips (id, depart, from, to, depart lane)."""
    body = "".join(f'    <trip id="{i}" type="car" depart="{t:.1f}" from="{a}" to="{b}" departLane="{lane}" '
                   f'departSpeed="max"/>\n' for i, t, a, b, lane in trips)
    path.write_text(f"<routes>\n{VTYPES_XML}{body}</routes>\n")
    return path


def _stall_inside(session: SumoSession, vehicle: str, prefixes: tuple[str, ...], limit_s: float = 60.0) -> None:
    """Step until ``vehicle`` is on one of the junction's internal lanes, then hold it there."""
    while session.time_s < limit_s:
        session.step()
        if vehicle in session.vehicle_ids and session.vehicle_lane(vehicle).startswith(prefixes):
            session.set_speed(vehicle, 0.0)
            return
    raise AssertionError(f"{vehicle} never entered the junction")


def test_standing_inside_is_removed_waiting_at_a_red_line_is_not(net: Path, tmp_path: Path) -> None:
    junction = read_junction(net)
    prefixes = internal_lane_prefixes(junction)
    routes = _routes(tmp_path / "r.rou.xml", [
        ("stalled", 0.0, "south_in", "north_out", 3),  # green for the south at t = 0: drives in
        ("waiting", 0.0, "east_in", "west_out", 3),  # red for the east for 65 s: waits at its line
    ])
    breaker = GridlockBreaker(junction, stand_s=20.0)
    removals = []
    with SumoSession().start(net, [routes], seed=1) as session:
        _stall_inside(session, "stalled", prefixes)
        while session.time_s < 55.0:
            session.step()
            removals += breaker.update(session)
        assert "waiting" in session.vehicle_ids
        assert session.standing_s("waiting") > 20.0  # it stood longer than the breaker's limit
    assert [r.participant for r in removals] == ["stalled"]
    removal = removals[0]
    assert removal.lane.startswith(prefixes) and 20.0 <= removal.stood_s < 21.5
    event = removal.to_event(12.34)
    assert event["event"] == "gridlock_removed" and event["value"]["id"] == "stalled"


@pytest.mark.parametrize("stand_s, expect_flow", [(None, False), (15.0, True)])
def test_a_junction_held_by_a_stalled_vehicle_flows_again_with_the_breaker(
        net: Path, tmp_path: Path, stand_s: float | None, expect_flow: bool) -> None:
    junction = read_junction(net)
    # the left-only lane: a left-turner stalled inside the junction holds every one behind it
    followers = [(f"follower{k}", 2.0 + 2.0 * k, "south_in", "west_out", 4) for k in range(4)]
    routes = _routes(tmp_path / "r.rou.xml", [("stalled", 0.0, "south_in", "west_out", 4), *followers])
    breaker = GridlockBreaker(junction, stand_s)
    arrived: set[str] = set()
    with SumoSession().start(net, [routes], seed=2) as session:
        _stall_inside(session, "stalled", internal_lane_prefixes(junction))
        while session.time_s < 58.0:  # the south keeps its green until 60 s
            alive = set(session.vehicle_ids)
            session.step()
            removed = {r.participant for r in breaker.update(session)}
            arrived |= alive - set(session.vehicle_ids) - removed
    followers_through = {f[0] for f in followers} & arrived
    assert bool(followers_through) is expect_flow
    if expect_flow:
        assert followers_through == {f[0] for f in followers}


def test_the_ego_is_never_a_candidate_and_off_means_off(net: Path, tmp_path: Path) -> None:
    junction = read_junction(net)
    routes = _routes(tmp_path / "r.rou.xml", [])
    with SumoSession().start(net, [routes], seed=3) as session:
        session.add_ego("ego", ["south_in", "north_out"], depart_lane=3)
        session.step()
        while not session.vehicle_lane("ego").startswith(internal_lane_prefixes(junction)):
            x, y, heading, _ = session.vehicle_pose("ego")
            session.move_ego("ego", x, y + 1.0, heading, 0.0)  # the south approach runs north
            session.step()
        on = GridlockBreaker(junction, stand_s=0.5)
        for _ in range(30):
            session.move_ego("ego", *session.vehicle_pose("ego")[:3], 0.0)
            session.step()
            assert on.update(session) == []
        assert session.has_vehicle("ego")
    with pytest.raises(ValueError, match="stand time"):
        GridlockBreaker(junction, stand_s=0.0)
    assert GridlockBreaker(junction, None).update(session) == []
