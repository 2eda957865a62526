"""Fixtures of the RL tests: one intersection's candidate paths and batches of states near them."""

from __future__ import annotations

import pytest

from crossroads.rl.buffer import StateBatch
from crossroads.rl.idc_model import IDCModel
from crossroads.rl.sampler import PathSet

from rl.rl_support import INTERSECTION, make_batch


@pytest.fixture(scope="session")
def path_set() -> PathSet:
    return PathSet.build((INTERSECTION,), ("left", "straight"))


@pytest.fixture()
def batch(path_set: PathSet) -> StateBatch:
    return make_batch(path_set, 8)


@pytest.fixture(scope="session")
def model(path_set: PathSet) -> IDCModel:
    return IDCModel(path_set.tensors())
