"""Traffic-light programs: pure logic, and the same logic checked against SUMO."""

from __future__ import annotations

import math
import subprocess
from dataclasses import replace
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crossroads.constants import (
    ALL_RED_S,
    CROSS_GREEN_S,
    CYCLE_S,
    GREEN_S,
    PEDESTRIAN_CLEARANCE_S,
    RED_S,
    YELLOW_S,
)
from crossroads.intersections import catalogue
from crossroads.network.junction import read_junction
from crossroads.intersections.build import find_netconvert
from crossroads.sim.signals import (
    LightAt,
    Phase,
    SignalError,
    TlProgram,
    apply_start,
    colours_of,
    light_at,
    live_light,
    movement_link,
    offset_for,
    phase_at,
    phase_for_light,
    read_all_programs,
    read_program,
    read_programs,
)
from crossroads.sim.sumo import SumoSession

PROG = TlProgram("t", "0", 0.0, (
    Phase(60.0, "Grg"), Phase(3.0, "yrg"), Phase(37.0, "rGg"), Phase(3.0, "ryg"),
))


def test_phase_and_light_at() -> None:
    assert PROG.cycle_s == 103.0
    assert phase_at(PROG, 0.0).index == 0
    assert phase_at(PROG, 61.0) == pytest.approx(type(phase_at(PROG, 61.0))(1, 1.0, 2.0))
    la = light_at(PROG, 0, 61.0)
    assert la.light == "yellow" and la.remaining_s == pytest.approx(2.0)  # t_y
    red = light_at(PROG, 0, 63.0)
    assert red.light == "red" and red.remaining_s == pytest.approx(40.0)  # the ego sees R40
    assert light_at(PROG, 0, 103.0 + 10.0).remaining_s == pytest.approx(50.0)
    assert light_at(PROG, 2, 5.0).remaining_s == math.inf  # right turn: always green
    assert light_at(PROG, 0, 5.0, offset_s=10.0).phase.index == 2  # (5 - 10) mod 103 = 98


@settings(max_examples=200, deadline=None)
@given(t=st.floats(0, 1e5), idx=st.integers(0, 3), frac=st.floats(0, 0.999))
def test_offset_for_puts_the_phase_there(t: float, idx: int, frac: float) -> None:
    elapsed = frac * PROG.phases[idx].duration_s
    off = offset_for(PROG, t, idx, elapsed)
    ph = phase_at(PROG, t, off)
    assert ph.index == idx
    assert ph.elapsed_s == pytest.approx(elapsed, abs=1e-6)


def test_bad_inputs() -> None:
    with pytest.raises(SignalError):
        TlProgram("x", "0", 0.0, (Phase(1.0, "G"), Phase(1.0, "GG")))
    with pytest.raises(SignalError):
        light_at(PROG, 7, 0.0)
    net = catalogue.build("a_single_lane")
    with pytest.raises(SignalError, match="no tlLogic"):
        read_program(net, "nope")


def test_catalogue_program_is_the_paper_cycle() -> None:
    net = catalogue.build("b_two_lane")
    j = read_junction(net)
    prog = read_program(net, j.tl_id)
    walk, clear = GREEN_S - PEDESTRIAN_CLEARANCE_S, PEDESTRIAN_CLEARANCE_S
    assert [p.duration_s for p in prog.phases] == [
        walk, clear, YELLOW_S, ALL_RED_S, CROSS_GREEN_S - clear, clear, YELLOW_S, ALL_RED_S]
    assert prog.cycle_s == CYCLE_S == GREEN_S + YELLOW_S + RED_S
    south = j.default_approach()
    straight = south.connections_for("straight")[0].tl_link_index
    # the ego's approach sees the paper's G60/Y3/R40
    assert [light_at(prog, straight, t).light for t in (0, 59.9, 61, 64, 102.9)] == [
        "green", "green", "yellow", "red", "red"]
    assert light_at(prog, straight, 0.0).remaining_s == GREEN_S
    assert light_at(prog, straight, 63.0).remaining_s == RED_S
    # a crossing parallel to the ego's axis: its walk ends PEDESTRIAN_CLEARANCE_S before that green
    parallel = next(c for c in j.crossings
                    if not any(e.startswith(("south", "north")) for e in c.crossed_edges))
    assert light_at(prog, parallel.tl_link_index, 0.0).light == "green"
    assert light_at(prog, parallel.tl_link_index, 0.0).remaining_s == walk
    assert light_at(prog, parallel.tl_link_index, walk + 0.1).light == "red"


def test_program_matches_sumo_with_and_without_a_start_phase() -> None:
    net = catalogue.build("b_two_lane")
    j = read_junction(net)
    prog = read_program(net, j.tl_id)
    links = sorted({c.tl_link_index for a in j.approaches for c in a.connections
                    if c.tl_link_index is not None})
    with SumoSession().start(net, seed=0) as sim:
        checks = 0
        for t_check in (0.5, 30.0, 60.5, 62.0, 63.5, 99.0, 101.5, 104.0, 170.3):
            while sim.time_s < t_check - 1e-6:
                sim.step()
            ph = phase_at(prog, sim.time_s)
            assert sim.tl_phase(j.tl_id) == ph.index
            assert sim.tl_state(j.tl_id) == prog.phases[ph.index].state
            assert sim.tl_time_to_switch_s(j.tl_id) == pytest.approx(ph.remaining_s, abs=1e-6)
            for k in links:
                assert live_light(sim, prog, k) == light_at(prog, k, sim.time_s)
            checks += 1
        # A scenario's start: cross-axis walk (phase 4) with 10 s already spent, from now on.
        offset = apply_start(sim, prog, 4, 10.0)
        for _ in range(12):
            sim.step(53)  # 5.3 s, so checks fall in every phase over two cycles
            ph = phase_at(prog, sim.time_s, offset)
            assert sim.tl_phase(j.tl_id) == ph.index
            assert sim.tl_time_to_switch_s(j.tl_id) == pytest.approx(ph.remaining_s, abs=1e-6)
            for k in links:
                assert sim.tl_state(j.tl_id)[k] == prog.phases[ph.index].state[k]
        assert len(sim.tl_controlled_links(j.tl_id)) == prog.n_links
    assert checks == 9


# --- several programs of one light, and the ego's colour ------------------------------------------


def _netgenerate_grid(out: Path) -> Path:
    """A 3×3 grid of traffic lights; the centre one, B1, has four legs."""
    netgenerate = Path(sys.executable).parent / "netgenerate"
    subprocess.run([str(netgenerate), "--grid", "--grid.number", "3", "--grid.length", "100",
                    "-j", "traffic_light", "--no-turnarounds", "-o", str(out)],
                   check=True, capture_output=True)
    return out


@pytest.fixture(scope="module")
def two_programs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A net whose light B1 has programs "0" (netconvert's, 4 phases) and "utopia" (8 phases, a
    shorter cycle), "utopia" written last: SUMO runs it, as a city net with a second program."""
    work = tmp_path_factory.mktemp("programs")
    grid = _netgenerate_grid(work / "grid.net.xml")
    first = read_program(grid, "B1")
    phases = "".join(f'<phase duration="{d:g}" state="{p.state}"/>'
                     for p, d in zip(first.phases * 2, (10, 3, 10, 3, 12, 3, 8, 3), strict=True))
    (work / "utopia.tll.xml").write_text(
        f'<tlLogics><tlLogic id="B1" type="static" programID="utopia" offset="0">{phases}'
        "</tlLogic></tlLogics>")
    net = work / "two.net.xml"
    subprocess.run([str(find_netconvert()), "-s", str(grid), "--tllogic-files",
                    str(work / "utopia.tll.xml"), "-o", str(net)], check=True, capture_output=True)
    return net


def _same(live: LightAt, computed: LightAt) -> None:
    assert (live.light, live.phase.index) == (computed.light, computed.phase.index)
    assert live.remaining_s == pytest.approx(computed.remaining_s, abs=1e-6)


def test_the_program_read_is_the_one_sumo_runs(two_programs: Path) -> None:
    """The last program loaded runs (SUMO's rule): read_program gives it by default, the other
    by its id; SUMO's phase index past the 4-phase program is never read against it."""
    every = read_all_programs(two_programs)["B1"]
    assert list(every) == ["0", "utopia"]
    running = read_program(two_programs, "B1")
    assert running.program_id == "utopia" and len(running.phases) == 8
    assert read_programs(two_programs)["B1"] is not None
    other = read_program(two_programs, "B1", "0")
    assert len(other.phases) == 4
    with pytest.raises(SignalError, match="has no program 'nope'; its programs: '0', 'utopia'"):
        read_program(two_programs, "B1", "nope")
    with SumoSession().start(two_programs, seed=0) as sim:
        assert sim.tl_program("B1") == "utopia"
        for _ in range(60):  # 42 s: past phase 3, the last index the 4-phase program has
            sim.step(7)  # 0.7 s: never on a phase boundary (where SUMO switches a step later)
            _same(live_light(sim, running, 0), light_at(running, 0, sim.time_s))
        assert sim.tl_phase("B1") >= 4
        with pytest.raises(SignalError, match="SUMO runs program 'utopia', not the one read"):
            live_light(sim, other, 0)
        # a scenario's choice of program: apply_start switches SUMO to it
        offset = apply_start(sim, other, 2, 1.0)
        assert sim.tl_program("B1") == "0"
        for _ in range(5):
            sim.step(37)
            _same(live_light(sim, other, 3), light_at(other, 3, sim.time_s, offset))


def test_phase_for_light_finds_the_ego_s_colour() -> None:
    # link 0: G60 y3 r37 r3 (the ego's straight); link 1: r r G y; link 2: always g (a right turn)
    assert phase_for_light(PROG, 0, "green") == (0, 0.0)
    assert phase_for_light(PROG, 0, "green", 12.5) == (0, 12.5)
    assert phase_for_light(PROG, 0, "yellow", 1.0) == (1, 1.0)
    assert phase_for_light(PROG, 0, "red") == (2, 0.0)
    assert phase_for_light(PROG, 0, "red", 38.0) == pytest.approx((3, 1.0))  # a red over two phases
    assert phase_for_light(PROG, 1, "green") == (2, 0.0)  # the cross axis: green from phase 2
    assert phase_for_light(PROG, 2, "green", 70.0) == pytest.approx((2, 7.0))  # always green
    with pytest.raises(SignalError, match="is never red: it shows green"):
        phase_for_light(PROG, 2, "red")
    with pytest.raises(SignalError, match="is green for 60 s at a time"):
        phase_for_light(PROG, 0, "green", 60.0)
    # a green that starts mid-cycle and wraps over the cycle's end: its first second is phase 3
    wrap = TlProgram("w", "0", 0.0, (Phase(5.0, "G"), Phase(3.0, "y"), Phase(20.0, "r"), Phase(10.0, "g")))
    assert phase_for_light(wrap, 0, "green") == (3, 0.0)
    assert phase_for_light(wrap, 0, "green", 12.0) == pytest.approx((0, 2.0))
    assert colours_of(wrap, 0) == ("green", "yellow", "red")


def test_the_ego_s_movement_link() -> None:
    j = read_junction(catalogue.build("b_two_lane"))
    south = j.default_approach()
    for task in ("left", "straight", "right"):
        conns = south.connections_for(task)
        lane = conns[-1].from_lane
        assert movement_link(south, task, lane) == next(c.tl_link_index for c in conns if c.from_lane == lane)
    with pytest.raises(SignalError, match="no signalised left movement"):
        movement_link(replace(south, connections=()), "left", "south_in_0")


@pytest.mark.parametrize("light", ["green", "yellow", "red"])
def test_the_world_starts_the_ego_s_light_in_the_colour_asked(light: str, two_programs: Path) -> None:
    """``lights: {ego: ...}`` on a net whose light runs a program of its own (netgenerate's grid,
    SUMO running "utopia"): the ego's link shows that colour at entry, ``elapsed_s`` into it."""
    from crossroads.sim.config import SignalStart, WorldConfig
    from crossroads.sim.traffic import NO_TRAFFIC
    from crossroads.sim.world import World

    cfg = WorldConfig(net_file=two_programs, task="straight", junction_id="B1", demand=NO_TRAFFIC,
                      warmup_s=7.0, timeout_s=5.0,
                      signal_start=SignalStart(ego_light=light, elapsed_s=1.0))
    with World(cfg) as world:
        assert world.program.program_id == "utopia"
        obs = world.reset(3)
        assert obs.light.light == light
        expected = light_at(world.program, world._link_index, 0.0,
                            offset_for(world.program, 0.0, *world.start_phase))
        assert obs.light.remaining_s == pytest.approx(expected.remaining_s - 0.1, abs=0.051)  # one step on
