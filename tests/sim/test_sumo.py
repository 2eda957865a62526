"""SumoSession against real SUMO runs (libsumo: one simulation per process, so sessions run one
after the other and are always closed)."""

from __future__ import annotations

import math
from pathlib import Path

import libsumo
import numpy as np
import pytest

from crossroads.geometry import point_at
from crossroads.intersections import catalogue
from crossroads.network.junction import read_junction
from crossroads.sim.sumo import EGO_LENGTH_M, EGO_WIDTH_M, SumoError, SumoSession, active_session
from crossroads.sim.traffic import TrafficDemand, write_routes

NET = "b_two_lane"


@pytest.fixture(scope="module")
def net_and_routes(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    net = catalogue.build(NET)
    junction = read_junction(net)
    d = tmp_path_factory.mktemp("sumo")
    r1 = write_routes(junction, TrafficDemand(), d / "s1.rou.xml", seed=1, duration_s=120)
    r2 = write_routes(junction, TrafficDemand(), d / "s2.rou.xml", seed=2, duration_s=120)
    return net, r1, r2


def _trajectory(net: Path, routes: Path, seed: int, steps: int) -> list[tuple]:
    out = []
    with SumoSession().start(net, [routes], seed=seed) as sim:
        for _ in range(steps):
            sim.step()
            s = sim.snapshot()
            out.append((s.ids.tolist(), s.kind.tolist(), s.x.copy(), s.y.copy(),
                        s.heading.copy(), s.speed.copy(), s.lane_id.tolist(), s.route))
    return out


def _same(a: list[tuple], b: list[tuple]) -> bool:
    for fa, fb in zip(a, b, strict=True):
        for va, vb in zip(fa, fb, strict=True):
            if isinstance(va, np.ndarray):
                if va.shape != vb.shape or not np.array_equal(va, vb):
                    return False
            elif va != vb:
                return False
    return True


def test_same_seed_same_snapshots_every_step_and_other_seed_differs(net_and_routes) -> None:
    net, r1, r2 = net_and_routes
    a = _trajectory(net, r1, 1, 300)
    b = _trajectory(net, r1, 1, 300)
    assert sum(len(f[0]) for f in a) > 0
    assert _same(a, b)
    c = _trajectory(net, r2, 2, 300)
    assert not _same(a, c)
    d = _trajectory(net, r1, 2, 300)  # same demand, other SUMO seed: driver randomness differs
    assert not _same(a, d)


def test_one_session_per_process_and_restart(net_and_routes) -> None:
    net, r1, _ = net_and_routes
    first = SumoSession().start(net, [r1], seed=0)
    try:
        assert active_session() is first
        with pytest.raises(SumoError, match="already running"):
            SumoSession().start(net, [r1], seed=0)
    finally:
        first.close()
    assert active_session() is None
    first.close()  # idempotent
    with first.start(net, [r1], seed=0) as again:  # restartable
        again.step(10)
        assert again.time_s == pytest.approx(1.0)
    assert not first.running


def test_bad_net_surfaces_sumo_message(tmp_path: Path) -> None:
    bad = tmp_path / "bad.net.xml"
    bad.write_text("this is not a network\n")
    with pytest.raises(SumoError, match="invalid document structure"):
        SumoSession().start(bad, seed=0)
    with pytest.raises(SumoError, match="not found"):
        SumoSession().start(tmp_path / "missing.net.xml", seed=0)
    assert active_session() is None


def test_snapshot_fields_and_centre_convention(net_and_routes) -> None:
    net, r1, _ = net_and_routes
    with SumoSession().start(net, [r1], seed=3) as sim:
        sim.step(600)
        s = sim.snapshot()
        assert len(s) > 10 and set(s.kind) <= {"vehicle", "cyclist", "pedestrian"}
        assert {"vehicle", "cyclist", "pedestrian"} <= set(s.kind)
        for i in np.flatnonzero(s.kind == "vehicle")[:5]:
            vid = str(s.ids[i])
            x, y, h, v = sim.vehicle_pose(vid)
            assert (x, y) == pytest.approx((s.x[i], s.y[i]), abs=1e-6)
            assert h == pytest.approx(s.heading[i], abs=1e-9)
            assert len(s.route[i]) >= 2
            assert s.edge_id[i].startswith(":") or s.edge_id[i] in s.route[i]
            assert s.lane_id[i].startswith(s.edge_id[i] + "_")
        assert np.all(np.abs(s.heading) <= math.pi)


def test_ego_footprint_exact_pose_and_followers_brake(tmp_path: Path) -> None:
    net = catalogue.build(NET)
    j = read_junction(net)
    south = j.default_approach()
    lane = south.entrance_lanes[0]
    conn = next(c for c in south.connections if c.from_lane == lane.id)
    exit_edge = conn.to_lane.rsplit("_", 1)[0]
    routes = tmp_path / "follower.rou.xml"
    routes.write_text(
        f'<routes><vType id="car" vClass="passenger" sigma="0"/>'
        f'<trip id="f0" type="car" depart="0" from="{south.incoming_edge}" to="{exit_edge}" '
        f'departLane="{lane.index}" departSpeed="max"/></routes>')
    with SumoSession().start(net, [routes], seed=0) as sim:
        sim.add_ego("ego", [south.incoming_edge, exit_edge], depart_lane=lane.index)
        s_ego = 0.6 * lane.length_m
        cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(lane.centerline, axis=0).T))])
        x = float(np.interp(s_ego, cum, lane.centerline[:, 0]))
        y = float(np.interp(s_ego, cum, lane.centerline[:, 1]))
        h = lane.start_heading
        # 0.3 m off the centre line, slightly rotated: SUMO must keep it exactly.
        cmd = (x + 0.3 * math.cos(h - math.pi / 2), y + 0.3 * math.sin(h - math.pi / 2), h + 0.02)
        sim.move_ego("ego", *cmd, 0.0)
        for _ in range(300):
            sim.step()
            sim.move_ego("ego", *cmd, 0.0)
            ex, ey, eh, ev = sim.vehicle_pose("ego")
            assert math.hypot(ex - cmd[0], ey - cmd[1]) < 0.01
            assert abs(eh - cmd[2]) < 1e-6
        assert "ego" not in set(sim.snapshot().ids)
        assert sim.vehicle_size("ego") == (EGO_LENGTH_M, EGO_WIDTH_M)
        snap = sim.snapshot()
        i = snap.index("f0")
        assert snap.speed[i] < 0.1  # stopped behind the ego
        gap = math.hypot(snap.x[i] - cmd[0], snap.y[i] - cmd[1]) - 0.5 * (EGO_LENGTH_M + snap.length[i])
        assert 0.5 < gap < 6.0


def test_an_ego_sumo_took_off_its_road_is_mapped_back_and_followers_still_stop(tmp_path: Path) -> None:
    """Placed more than half a lane and half its width off every lane of its route, SUMO takes the
    ego off its road network, where its followers no longer see it. The next placement maps it onto
    its route's lane (snapped to the centre), so a follower stops behind it; once its pose is back
    within the lane, it is placed exactly again."""
    net = catalogue.build(NET)
    j = read_junction(net)
    south = j.default_approach()
    lane = south.entrance_lanes[0]
    conn = next(c for c in south.connections if c.from_lane == lane.id)
    exit_edge = conn.to_lane.rsplit("_", 1)[0]
    routes = tmp_path / "follower.rou.xml"
    routes.write_text(
        f'<routes><vType id="car" vClass="passenger" sigma="0"/>'
        f'<trip id="f0" type="car" depart="0" from="{south.incoming_edge}" to="{exit_edge}" '
        f'departLane="{lane.index}" departSpeed="max"/></routes>')
    h = lane.start_heading
    x, y = point_at(lane.centerline, 0.6 * lane.length_m)
    right = (math.cos(h - math.pi / 2), math.sin(h - math.pi / 2))
    off = 0.5 * (lane.width_m + EGO_WIDTH_M) + 0.5  # beyond what SUMO keeps on the lane

    def pose(offset: float) -> tuple[float, float, float]:
        return float(x + offset * right[0]), float(y + offset * right[1]), h

    with SumoSession().start(net, [routes], seed=0) as sim:
        sim.add_ego("ego", [south.incoming_edge, exit_edge], depart_lane=lane.index)
        sim.move_ego("ego", *pose(0.0), 0.0)
        sim.step()
        lanes = []
        for _ in range(300):
            sim.move_ego("ego", *pose(off), 0.0)
            sim.step()
            lanes.append(libsumo.vehicle.getLaneID("ego"))
        assert lanes[0] == ""  # SUMO took it off: the exact pose lies off every lane
        assert set(lanes[1:]) == {lane.id}  # and from then on it is mapped onto the lane
        snap = sim.snapshot()
        i = snap.index("f0")
        assert snap.speed[i] < 0.1  # stopped behind the ego
        gap = math.hypot(snap.x[i] - x, snap.y[i] - y) - 0.5 * (EGO_LENGTH_M + snap.length[i])
        assert 0.5 < gap < 6.0
        ex, ey, _, _ = sim.vehicle_pose("ego")
        assert math.hypot(ex - x, ey - y) < 0.01  # on the centre line
        sim.move_ego("ego", *pose(0.3), 0.0)  # back within the lane: placed exactly again
        sim.step()
        ex, ey, _, _ = sim.vehicle_pose("ego")
        assert math.hypot(ex - pose(0.3)[0], ey - pose(0.3)[1]) < 0.01


def test_paper_demand_populates_the_snapshot(tmp_path: Path) -> None:
    """Under the paper's demand the intersection holds many participants, all with finite poses.
    (Speed is measured in benchmarks/episode_speed.py, never in a unit test.)"""
    net = catalogue.build("c_three_lane")
    j = read_junction(net)
    routes = write_routes(j, TrafficDemand(), tmp_path / "rate.rou.xml", seed=5,
                          duration_s=200)
    with SumoSession().start(net, [routes], seed=5) as sim:
        sim.step(450)
        snap = sim.snapshot()
    assert len(snap) >= 60
    assert np.isfinite(np.column_stack([snap.x, snap.y, snap.heading, snap.speed])).all()


def test_static_columns_follow_arrivals_and_departures(net_and_routes) -> None:
    """The snapshot's static columns (built from the session's table of participants, partly
    reused between steps) always equal what SUMO says about each participant."""
    net, r1, _ = net_and_routes
    with SumoSession().start(net, [r1], seed=4) as sim:
        sim.step(300)
        changes, previous = 0, None
        for _ in range(200):
            sim.step()
            s = sim.snapshot()
            changes += previous is not None and previous != s.ids.tolist()
            previous = s.ids.tolist()
            assert s.ids.dtype == np.array(s.ids.tolist(), dtype=np.str_).dtype
            persons = set(sim.person_ids)
            for i, pid in enumerate(previous):
                st = sim._read_static(pid, pid in persons)
                assert (s.kind[i], s.length[i], s.width[i], s.route[i]) == (
                    st.kind, st.length_m, st.width_m, st.route)
                assert s.kind_code[i] == ("vehicle", "cyclist", "pedestrian").index(st.kind)
            rows = s.observation_rows
            np.testing.assert_array_equal(rows, np.column_stack([s.x, s.y, s.speed, s.heading, s.length, s.width]))
        assert changes > 10  # participants came and went


def test_static_table_grows_and_forgets() -> None:
    from crossroads.sim.sumo import _Static, _StaticTable

    table = _StaticTable()
    for k in range(600):  # past its first capacity, twice
        table.add(f"p{k}", _Static("cyclist" if k % 3 else "pedestrian", 1.0 + k, 0.5 + k, (f"e{k}",)))
    ids = ("p599", "p0", "p300")
    rows = table.rows(ids)
    assert table.length[rows].tolist() == [600.0, 1.0, 301.0] and table.width[rows].tolist() == [599.5, 0.5, 300.5]
    assert table.half_length[rows].tolist() == [300.0, 0.5, 150.5] and table.kind_code[rows].tolist() == [1, 2, 2]
    table.forget("p0")
    with pytest.raises(KeyError):
        table.rows(ids)
    table.add("p0", _Static("vehicle", 4.5, 1.8, ("a", "b")))  # back under a new row
    assert table.kind_code[table.rows(("p0",))].tolist() == [0] and table.route["p0"] == ("a", "b")


def _lane_changes_inside_the_junction(net: Path, routes: Path, forbid: bool, steps: int) -> int:
    """How often a vehicle moved from one internal lane to another of the same internal edge (a
    lane change inside the junction, SUMO's sideways jump) in ``steps`` steps."""
    changes = 0
    with SumoSession().start(net, [routes], seed=5) as sim:
        if forbid:
            sim.forbid_lane_changes(lane for lane in sim.lane_ids() if lane.startswith(":"))
        last: dict[str, str] = {}
        for _ in range(steps):
            sim.step()
            lanes = sim.vehicle_lanes()
            for vid, lane in lanes.items():
                before = last.get(vid, "")
                if lane.startswith(":") and before.startswith(":") and lane != before \
                        and lane.rsplit("_", 1)[0] == before.rsplit("_", 1)[0]:
                    changes += 1
            last = lanes
    return changes


def test_forbidden_lane_changes_inside_the_junction_do_not_happen(tmp_path: Path) -> None:
    """b_two_lane's straight movements run over two parallel internal lanes of one edge, and SUMO's
    drivers change between them; with the change permissions taken away they do not."""
    net = catalogue.build(NET)
    routes = write_routes(read_junction(net), TrafficDemand(vehicles_per_hour=800), tmp_path / "r.rou.xml",
                          seed=5, duration_s=400)
    assert _lane_changes_inside_the_junction(net, routes, forbid=False, steps=3000) > 0
    assert _lane_changes_inside_the_junction(net, routes, forbid=True, steps=3000) == 0


def test_a_vehicle_held_by_two_rules_stands_until_both_have_released_it(net_and_routes) -> None:
    """Two of the world's rules holding one car (the courtesy for a standing ego, the letting out
    of one caught inside the junction): one letting go must not release the other's hold."""
    net, routes, _ = net_and_routes
    with SumoSession().start(net, [routes], seed=1) as sim:
        sim.step(40)
        vid = next(v for v in sim.vehicle_ids if sim.vehicle_pose(v)[3] > 3.0)

        def speed_after(steps: int) -> float:
            sim.step(steps)
            return sim.vehicle_pose(vid)[3]

        sim.hold_vehicle(vid, "courtesy")
        sim.hold_vehicle(vid, "letting_out")
        assert speed_after(30) == 0.0
        sim.release_vehicle(vid, "letting_out")
        sim.release_vehicle(vid, "somebody else")  # holds nothing: changes nothing
        assert sim.vehicle_holders(vid) == {"courtesy"}
        assert speed_after(20) == 0.0
        sim.release_vehicle(vid, "courtesy")
        assert not sim.vehicle_holders(vid)
        assert speed_after(20) > 0.5
