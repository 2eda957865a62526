"""benchmarks/world_flow.py runs its episodes through the batch workers of ``crossroads evaluate``
(whose fork per episode tests/evaluation/test_executors.py pins): one row per seed, in the seeds'
order, the same rows whatever the order of the seeds and the number of workers."""

from __future__ import annotations

import sys

import pytest
import yaml
from support import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "benchmarks"))
from world_flow import _episodes  # noqa: E402

SHORT_STRAIGHT = {  # the nominal straight of a_single_lane, short: warm-up and time limit cut
    **yaml.safe_load((REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-straight.yaml").read_text()),
    "warmup_s": 10.0,
    "timeout_s": 12.0,
}
SEEDS = [20261206, 7, 1311414304]


@pytest.mark.slow
def test_each_seed_ends_the_same_in_any_order_and_rows_follow_the_seeds(tmp_path) -> None:
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(SHORT_STRAIGHT))
    forward = _episodes(path, "rule", SEEDS, workers=2)
    backward = _episodes(path, "rule", SEEDS[::-1], workers=1)
    assert [row["seed"] for row in forward] == SEEDS
    assert forward == backward[::-1]
    for row in forward:
        assert row["outcome"] in {"passed", "collision", "red_light", "off_road", "timeout"}
        assert set(row) == {"seed", "outcome", "time_s", "travel_time_s", "blocked_by", "removed", "detail"}
