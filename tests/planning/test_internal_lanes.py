"""SUMO's internal lanes against the candidate paths of the same movements."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from crossroads.constants import INTERNAL_LANE_OFFSET_WARN_M
from crossroads.intersections.resolve import open_junction
from crossroads.planning.internal_lanes import internal_lane_offsets, offset_warning, worst_offset
from support import SUMO_CROSS_NET, sumo_example


@pytest.fixture(scope="module")
def c_three_lane():
    return open_junction("c_three_lane")


def test_a_catalogue_build_draws_every_internal_lane_along_its_path(c_three_lane) -> None:
    offsets = internal_lane_offsets(c_three_lane)
    assert len(offsets) == sum(len(a.connections) for a in c_three_lane.approaches) == 36
    assert all(o.problem is None and o.max_m is not None and o.max_m < 0.05 for o in offsets)
    assert offset_warning(offsets, "c_three_lane") is None


def test_an_internal_lane_moved_sideways_is_measured_by_the_move(c_three_lane) -> None:
    """Shift one left turn's internal lane 1.5 m east: the Hausdorff distance is at most the shift
    (plus the few mm they were apart), above the warning, and the warning names that movement."""
    approach = c_three_lane.default_approach()
    left = next(c for c in approach.connections if c.turn == "left")
    shifted = dataclasses.replace(left, via_shape=left.via_shape + np.array([1.5, 0.0]))
    moved = dataclasses.replace(approach, connections=tuple(
        shifted if c is left else c for c in approach.connections))
    junction = dataclasses.replace(c_three_lane, approaches=tuple(
        moved if a is approach else a for a in c_three_lane.approaches))
    before = next(o for o in internal_lane_offsets(c_three_lane)
                  if (o.from_lane, o.to_lane) == (left.from_lane, left.to_lane))
    offsets = internal_lane_offsets(junction)
    worst = worst_offset(offsets)
    assert worst is not None and (worst.from_lane, worst.to_lane) == (left.from_lane, left.to_lane)
    # the triangle inequality: the shift plus how far apart the two ran before
    assert 1.0 < worst.max_m <= 1.5 + before.max_m + 1e-9 and worst.mean_m is not None and 0.5 < worst.mean_m < 1.5
    assert sum(o.above_warning for o in offsets) == 1
    warning = offset_warning(offsets, "moved")
    assert warning is not None and f"{left.from_lane} -> {left.to_lane}" in warning


def test_a_movement_without_an_internal_lane_says_so(c_three_lane) -> None:
    approach = c_three_lane.default_approach()
    bare = dataclasses.replace(approach, connections=tuple(
        dataclasses.replace(c, via_lane=None, via_shape=None) for c in approach.connections))
    junction = dataclasses.replace(c_three_lane, approaches=(bare,))
    offsets = internal_lane_offsets(junction)
    assert offsets and all(o.max_m is None and "no internal lane" in (o.problem or "") for o in offsets)
    assert worst_offset(offsets) is None and offset_warning(offsets, "bare") is None


def test_a_u_turn_is_measured_but_never_judged(c_three_lane) -> None:
    """`net check --max-offset`, the warnings and the API judge only the movements that are tasks:
    a U-turn whose internal lane runs 3 m off is listed, not marked, not the worst."""
    approach = c_three_lane.default_approach()
    left = next(c for c in approach.connections if c.turn == "left")
    uturn = dataclasses.replace(left, turn="uturn", via_shape=left.via_shape + np.array([3.0, 0.0]))
    moved = dataclasses.replace(approach, connections=tuple(
        uturn if c is left else c for c in approach.connections))
    junction = dataclasses.replace(c_three_lane, approaches=tuple(
        moved if a is approach else a for a in c_three_lane.approaches))
    offsets = internal_lane_offsets(junction)
    measured = next(o for o in offsets if o.turn == "uturn")
    assert measured.max_m is not None and measured.max_m > 2.5
    assert not measured.is_task and not measured.above_warning and measured.to_json()["above_warning"] is False
    worst = worst_offset(offsets)
    assert worst is not None and worst.turn != "uturn" and worst.max_m < 0.05
    assert offset_warning(offsets, "uturn") is None


def test_netconverts_own_lanes_on_a_hand_drawn_net_are_flagged() -> None:
    """SUMO's example cross.net.xml: netconvert's left turns run up to 3.1 m from the paper's
    Bezier paths (ρ = 0.6: 3.149 m, 4si_1 -> 2o_0), 2.76 m from the planner's (1si_2 -> 4o_0), its
    straight movements along them."""
    offsets = internal_lane_offsets(open_junction(sumo_example(SUMO_CROSS_NET)))
    worst = worst_offset(offsets)
    assert worst is not None and worst.turn == "left" and worst.max_m > 2.5
    straight = [o.max_m for o in offsets if o.turn == "straight" and o.max_m is not None]
    assert straight and max(straight) < INTERNAL_LANE_OFFSET_WARN_M
