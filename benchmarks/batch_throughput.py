"""Batch throughput: episodes per minute with 1 and 2 local worker processes and with local Ray.

    .venv/bin/python benchmarks/batch_throughput.py [--scenario scenarios/nominal/a_single_lane-left.yaml]
        [--timeout-s 20] [--episodes 12] [--no-ray] [--policy rule|MODEL.pt]

Each configuration runs one fresh batch of ``--episodes`` episodes of the scenario (its timeout
cut to ``--timeout-s``) with the rule controller (or ``--policy``) into a temporary SQLite store, traces off, so the
figure is the whole path a real batch takes: worker start-up, episodes, one committed row each.
Printed per configuration: the rate over the batch's whole wall time, and the steady rate (from
the first recorded episode to the last, i.e. without start-up). Then the scaling ratio
(2 workers / 1 worker, steady) and the projected time of the paper suite
(2 policies × 6 cases × 200 runs = 2400 episodes) at the measured 2-worker rate.
Target (issue #5): the paper suite in ≤ 15 min on this 2-core machine.

Note: the paper cases have a 60 s warm-up and heavier traffic than this short scenario, and
trained policies decide slower than the rule controller; the projection is for this scenario's
episode cost (run with --scenario scenarios/paper/overspeed-50.yaml for a heavier one).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

REPO = Path(__file__).resolve().parents[1]
PAPER_SUITE_EPISODES = 2 * 6 * 200
TARGET_MIN = 15.0


def measure(store, spec, base_dir: Path, data_dir: Path, *, workers: int,  # type: ignore[no-untyped-def]
            ray_address: str | None, policy: str) -> tuple[float, float, int]:
    """(total rate, steady rate) in episodes/min, and the errors of one fresh batch."""
    from crossroads.evaluation.batch import BatchRunner, create_batch_for

    batch_id = create_batch_for(store, spec=spec, policy=policy, traces="none", base_dir=base_dir)
    stamps: list[float] = []
    start = time.perf_counter()
    result = BatchRunner(store, batch_id, workers=workers, ray_address=ray_address, data_dir=data_dir,
                         on_progress=lambda d, t, last: last and stamps.append(time.perf_counter())).run()
    total = time.perf_counter() - start
    n = result.recorded
    steady = (n - 1) / (stamps[-1] - stamps[0]) * 60.0 if n > 1 and stamps[-1] > stamps[0] else float("nan")
    return n / total * 60.0, steady, result.errors


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", type=Path, default=REPO / "scenarios/nominal/a_single_lane-left.yaml")
    parser.add_argument("--timeout-s", type=float, default=20.0)
    parser.add_argument("--episodes", type=int, default=12)
    parser.add_argument("--no-ray", action="store_true", help="skip the local Ray measurement")
    parser.add_argument("--policy", default="rule", help="'rule' or a model (.pt), e.g. models/apg.pt")
    args = parser.parse_args()

    from crossroads.scenario.spec import load_scenario
    from crossroads.store import open_store

    spec = load_scenario(args.scenario).model_copy(
        update={"timeout_s": args.timeout_s, "runs": args.episodes})
    configs: list[tuple[str, int, str | None]] = [
        ("1 worker (local)", 1, None), ("2 workers (local)", 2, None)]
    if not args.no_ray:
        configs.append(("2 workers (local Ray)", 2, "local"))
    print(f"scenario {spec.name}, timeout {spec.timeout_s:g} s, warm-up {spec.warmup_s:g} s, "
          f"{args.episodes} episodes per configuration, policy {args.policy}, {os.cpu_count()} CPUs")
    rates: dict[int | str, float] = {}
    with tempfile.TemporaryDirectory(prefix="crossroads-bench-") as tmp:
        store = open_store(f"sqlite:///{tmp}/bench.db")
        for label, workers, ray_address in configs:
            total, steady, errors = measure(store, spec, args.scenario.parent, Path(tmp),
                                            workers=workers, ray_address=ray_address, policy=args.policy)
            rates[ray_address or workers] = steady
            rates[f"total-{ray_address or workers}"] = total
            print(f"  {label:<24} {total:7.1f} episodes/min overall   {steady:7.1f} episodes/min steady"
                  + (f"   ({errors} errors)" if errors else ""))
        store.close()
    print(f"scaling 2 workers / 1 worker (steady): {rates[2] / rates[1]:.2f}x "
          f"(overall {rates['total-2'] / rates['total-1']:.2f}x)")
    if "local" in rates:
        print(f"local Ray / local processes, 2 workers (steady): {rates['local'] / rates[2]:.2f}x")
    minutes = PAPER_SUITE_EPISODES / rates["total-2"]
    print(f"paper suite ({PAPER_SUITE_EPISODES} episodes) at the 2-worker overall rate: {minutes:.1f} min "
          f"(target ≤ {TARGET_MIN:g} min: {'met' if minutes <= TARGET_MIN else 'NOT met'})")


if __name__ == "__main__":
    main()
