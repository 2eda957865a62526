"""benchmarks/episode_fingerprints.py: the same episodes give the same lines, and a changed
episode is told apart."""

from __future__ import annotations

import json
import sys

import yaml
from support import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "benchmarks"))
from episode_fingerprints import compare, fingerprint, seed_range  # noqa: E402


def test_the_same_episodes_compare_equal_and_a_changed_one_differs(tmp_path, capsys) -> None:
    scenario = tmp_path / "short.yaml"
    spec = yaml.safe_load((REPO_ROOT / "scenarios" / "nominal" / "a_single_lane-straight.yaml").read_text())
    spec.update(warmup_s=10.0, timeout_s=6.0)  # short: warm-up and time limit cut
    scenario.write_text(yaml.safe_dump(spec))
    first, second = tmp_path / "first.jsonl", tmp_path / "second.jsonl"
    fingerprint(first, [str(scenario)], ["rule"], seed_range("7001-7002"))
    fingerprint(second, [str(scenario)], ["rule"], seed_range("7001-7002"))
    assert compare(first, second) == 0
    lines = [json.loads(line) for line in second.read_text().splitlines()]
    assert len(lines) == 2 and lines[0][2] == 7001
    lines[1][3]["steps"] += 1
    second.write_text("".join(json.dumps(line) + "\n" for line in lines))
    assert compare(first, second) == 1
    assert "differs" in capsys.readouterr().out
