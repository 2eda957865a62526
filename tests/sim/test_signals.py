"""Traffic-light programs: pure logic, and the same logic checked against SUMO."""

from __future__ import annotations

import math
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crossroads.constants import CROSS_GREEN_S, GREEN_S, YELLOW_S
from crossroads.network import catalogue
from crossroads.network.junction import read_junction
from crossroads.sim.signals import (
    Phase,
    SignalError,
    TlProgram,
    apply_start,
    light_at,
    live_light,
    offset_for,
    phase_at,
    read_program,
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
    assert [p.duration_s for p in prog.phases] == [GREEN_S, YELLOW_S, CROSS_GREEN_S, YELLOW_S]
    south = j.default_approach()
    straight = south.connections_for("straight")[0].tl_link_index
    assert [light_at(prog, straight, t).light for t in (0, 61, 64)] == ["green", "yellow", "red"]


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
        # A scenario's start: cross-axis green with 10 s already spent, from now on.
        offset = apply_start(sim, prog, 2, 10.0)
        for _ in range(12):
            sim.step(53)  # 5.3 s, so checks fall in every phase over two cycles
            ph = phase_at(prog, sim.time_s, offset)
            assert sim.tl_phase(j.tl_id) == ph.index
            assert sim.tl_time_to_switch_s(j.tl_id) == pytest.approx(ph.remaining_s, abs=1e-6)
            for k in links:
                assert sim.tl_state(j.tl_id)[k] == prog.phases[ph.index].state[k]
        assert len(sim.tl_controlled_links(j.tl_id)) == prog.n_links
    assert checks == 9
