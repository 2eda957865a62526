"""The clutter probe (benchmarks/research/clutter_probe.py): which vehicle is ahead, the slot rearrangements,
and whether a plan meets one given participant."""

from __future__ import annotations

import sys

import numpy as np
import torch
from support import REPO_ROOT

from crossroads.idc.decision import IdcController
from crossroads.idc.state import pad_participant, path_tensors
from crossroads.rl.buffer import Samples
from crossroads.rl.idc_model import IDCModel
from crossroads.rl.neural_nets import make_networks
from crossroads.rl.sampler import PathSet

sys.path.insert(0, str(REPO_ROOT / "benchmarks" / "research"))
from clutter_probe import PlanProbe, moved_first, only_slot, pair_as_built, real_slots  # noqa: E402
from probing import vehicle_ahead  # noqa: E402

PATHS = PathSet.build(("a_single_lane",), ("straight",))


def scene(ahead_m: tuple[float, ...], slots: tuple[int, ...]) -> Samples:
    """The ego at 8 m/s on the first straight path, standing cars ``ahead_m`` [m] ahead of its
    centre on the path in ``slots``, every other slot padded; the pass mode."""
    path = PATHS.candidates[0]
    x, y, heading, _ = path.reference_at(20.0)
    ego = np.array([x, y, 8.0, 0.0, heading, 0.0, 0.0, 0.0])
    others = np.tile(pad_participant(ego), (16, 1))
    for along, slot in zip(ahead_m, slots, strict=True):
        cx, cy, ch, _ = path.reference_at(20.0 + along)
        others[slot] = (cx, cy, 0.0, ch, 5.0, 1.8)
    return Samples(ego[None].astype(np.float32), others[None].astype(np.float32), np.zeros((1, 16), np.float32),
                   np.array([0]), np.array([False]))


def test_the_vehicle_ahead_and_the_slot_rearrangements() -> None:
    s = scene((40.0, 12.0, 25.0), (0, 3, 5))
    ego, others = s.ego[0].astype(np.float64), s.others[0].astype(np.float64)
    assert vehicle_ahead(ego, others) == 3 and real_slots(ego, others) == [0, 3, 5]
    moved = moved_first(s, np.array([3]))
    assert np.array_equal(moved.others[0, 0], s.others[0, 3])
    assert np.array_equal(moved.others[0, 1:4], s.others[0, 0:3])  # the slots before it, one on
    assert np.array_equal(moved.others[0, 4:], s.others[0, 4:])
    alone = only_slot(s, np.array([3]), keep_slot=False)
    assert np.array_equal(alone.others[0, 0], s.others[0, 3]) and real_slots(ego, alone.others[0]) == [0]
    kept = only_slot(s, np.array([3]), keep_slot=True)
    assert real_slots(ego, kept.others[0]) == [3]
    pair, car = pair_as_built(s, 0, 0, 3)  # the car 40 m ahead and the one 12 m ahead, sorted by distance
    assert car[0] == 1 and np.array_equal(pair.others[0, 0], s.others[0, 3]) and real_slots(ego, pair.others[0]) == [0, 1]
    assert vehicle_ahead(ego, scene((), ()).others[0].astype(np.float64)) is None


def test_a_plan_meets_only_the_participant_it_is_asked_about() -> None:
    torch.manual_seed(0)
    nets = make_networks("dpg", 2, 16)
    with torch.no_grad():  # mean action 0: no jerk, no steering, so the ego rolls on at 8 m/s
        nets.policy.net[-1].weight.zero_()
        nets.policy.net[-1].bias[:2].zero_()
    probe = PlanProbe(IDCModel(path_tensors(PATHS.candidates, dtype=torch.float32)),
                      IdcController(nets.policy, nets.value))
    s = scene((60.0, 10.0), (0, 1))  # 2.5 s at 8 m/s reach 20 m: the car 10 m ahead is met, not the far one
    assert probe.meets(s, np.array([1]))[0]
    assert not probe.meets(s, np.array([0]))[0]
