"""Every detail of a fixed set of episodes, to show a speed-up left the episodes as they were.

    .venv/bin/python benchmarks/episode_fingerprints.py OUT.jsonl [--seeds 7001-7006] \
        [--policy rule --policy sumo] [--scenario scenarios/nominal/c_three_lane-left.yaml ...]
    PYTHONPATH=<other tree>/backend .venv/bin/python benchmarks/episode_fingerprints.py OTHER.jsonl
    .venv/bin/python benchmarks/episode_fingerprints.py --compare OUT.jsonl OTHER.jsonl

Runs each scenario and policy on the given seeds, one world per scenario and policy in this one
process (so two trees run the same sequence), and writes a JSON line per episode: the scenario,
the policy, the seed and the whole episode result (outcome, steps, time, travel time, the closest
distances and gaps, every event). ``--compare`` prints how many lines of two such files are the same
and every difference. Run it on a tree before and after a change that should not change what the
world or a controller does (a fast path): identical files say it did not, on these episodes.
The seeds default to 7001–7006, other than the scenarios' own base seed 0.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DEFAULT_SCENARIOS = [f"scenarios/nominal/{name}.yaml" for name in (
    "c_three_lane-left", "b_two_lane-left", "e_irregular_oblique-left", "f_irregular_wide-right",
    "a_single_lane-straight")] + ["scenarios/paper/rounding-50.yaml"]


def seed_range(text: str) -> list[int]:
    """``"7001-7006"`` or ``"7001"`` as the list of seeds."""
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def fingerprint(out: Path, scenarios: list[str], policies: list[str], seeds: list[int]) -> None:
    from crossroads.evaluation.episode import run_episode
    from crossroads.evaluation.policies import load_controller
    from crossroads.policy.ref import parse_policy
    from crossroads.scenario.spec import load_scenario, to_world_config
    from crossroads.sim.world import World

    with out.open("w") as sink:
        for scenario in scenarios:
            path = (REPO / scenario) if not Path(scenario).is_absolute() else Path(scenario)
            for policy in policies:
                with World(to_world_config(load_scenario(path), path.parent)) as world:
                    for seed in seeds:
                        result = run_episode(world, load_controller(parse_policy(policy)), seed=seed)
                        sink.write(json.dumps([scenario, policy, seed, result.to_json()]) + "\n")
                        sink.flush()
                        print(f"{scenario} {policy} {seed}: {result.outcome} after {result.time_s:.1f} s")


def compare(first: Path, second: Path) -> int:
    """Prints the lines two fingerprint files share and every difference; 1 when any differ."""
    a = [json.loads(line) for line in first.read_text().splitlines()]
    b = [json.loads(line) for line in second.read_text().splitlines()]
    same = 0
    for x, y in zip(a, b, strict=False):
        if x == y:
            same += 1
            continue
        fields = {k: (x[3].get(k), y[3].get(k)) for k in x[3] if x[3].get(k) != y[3].get(k)}
        print(f"differs: {x[:3]} {fields}")
    print(f"{same} of {len(a)} episodes identical ({len(b)} in the second file)")
    return 0 if same == len(a) == len(b) else 1


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, nargs="?")
    parser.add_argument("--compare", nargs=2, type=Path, metavar=("FIRST", "SECOND"))
    parser.add_argument("--seeds", default="7001-7006")
    parser.add_argument("--policy", action="append", dest="policies")
    parser.add_argument("--scenario", action="append", dest="scenarios")
    args = parser.parse_args()
    if args.compare:
        return compare(*args.compare)
    if args.out is None:
        parser.error("give OUT.jsonl, or --compare FIRST SECOND")
    fingerprint(args.out, args.scenarios or DEFAULT_SCENARIOS, args.policies or ["rule", "sumo"],
                seed_range(args.seeds))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
