"""The replay buffer: ring semantics, uniform and danger-weighted draws, danger scores in checkpoints."""

from __future__ import annotations

import numpy as np
import pytest

from crossroads.rl.buffer import ReplayBuffer, Samples
from crossroads.rl.config import TrainConfig


def samples(n: int, start: int = 0) -> Samples:
    """n states whose ego x is their serial number (to tell them apart)."""
    ego = np.zeros((n, 8), np.float32)
    ego[:, 0] = np.arange(start, start + n)
    return Samples(ego, np.zeros((n, 16, 6), np.float32), np.zeros((n, 16), np.float32),
                   np.zeros(n, np.int64), np.zeros(n, bool))


def test_without_a_danger_share_the_draws_are_the_uniform_ones() -> None:
    a, b = ReplayBuffer(100, seed=3), ReplayBuffer(100, seed=3)
    a.add(samples(50), danger=np.linspace(0, 10, 50))
    b.add(samples(50))
    expected = np.random.default_rng(3).integers(0, 50, size=32)  # what the buffer always drew
    assert np.array_equal(a.draw(32), expected)  # scores alone change nothing
    assert np.array_equal(b.draw(32, danger_share=0.0), expected)


def test_a_danger_share_of_the_batch_comes_from_the_dangerous_states() -> None:
    buffer = ReplayBuffer(1000, seed=0)
    danger = np.zeros(1000, np.float32)
    danger[[7, 70, 700]] = [5.0, 2.0, 0.5]  # 0.5 is under the threshold
    buffer.add(samples(1000), danger=danger)
    idx = buffer.draw(256, danger_share=0.5, danger_threshold=1.0)
    assert len(idx) == 256
    assert set(idx[128:].tolist()) <= {7, 70}  # the dangerous half
    assert np.isin(idx[:128], [7, 70]).sum() < 10  # the uniform half: ~0.5 expected
    batch = buffer.batch(idx)
    assert batch.ego.shape == (256, 8) and set(batch.ego[128:, 0].tolist()) <= {7.0, 70.0}


def test_uniform_alone_while_nothing_is_dangerous_and_rescoring_changes_that() -> None:
    buffer = ReplayBuffer(100, seed=1)
    buffer.add(samples(100))
    assert len(buffer.draw(64, danger_share=0.5)) == 64  # no dangerous state yet: all uniform
    buffer.rescore(np.array([42]), np.array([9.0], np.float32))
    idx = buffer.draw(64, danger_share=0.5)
    assert np.all(idx[32:] == 42)


def test_ring_overwrites_scores_with_their_states_and_checkpoints_keep_them() -> None:
    buffer = ReplayBuffer(10, seed=0)
    buffer.add(samples(8), danger=np.full(8, 3.0))
    buffer.add(samples(4, start=8))  # wraps: slots 8, 9, 0, 1 get new states with score 0
    assert buffer.danger.tolist() == [0, 0, 3, 3, 3, 3, 3, 3, 0, 0]
    assert buffer.ego[0, 0] == 10 and buffer.ego[2, 0] == 2
    restored = ReplayBuffer(10, seed=5)
    restored.load_state_dict(buffer.state_dict())
    assert np.array_equal(restored.danger, buffer.danger)
    assert np.array_equal(restored.draw(16, 0.5), buffer.draw(16, 0.5))


def test_checkpoints_from_before_the_scores_load_with_zero_danger() -> None:
    buffer = ReplayBuffer(10, seed=0)
    buffer.add(samples(5), danger=np.ones(5))
    state = buffer.state_dict()
    del state["danger"]
    restored = ReplayBuffer(10)
    restored.load_state_dict(state)
    assert not restored.danger.any()


@pytest.mark.parametrize("field,value", [("danger_share", 1.5), ("danger_share", -0.1), ("danger_threshold", -1.0)])
def test_config_rejects_bad_danger_settings(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        TrainConfig(**{field: value})


def test_take_selects_the_same_rows_of_every_field() -> None:
    s = samples(6)
    part = s.take(np.array([4, 1]))
    assert len(part) == 2 and part.path.tolist() == [s.path[4], s.path[1]]
    for field in Samples._fields:
        assert np.array_equal(getattr(part, field), getattr(s, field)[[4, 1]])
    assert np.array_equal(s.take(slice(2, 4)).ego, s.ego[2:4])
