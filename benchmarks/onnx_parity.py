"""The shipped APG exported to ONNX drives as the checkpoint does: the same outcome, run by run.

    .venv/bin/python benchmarks/onnx_parity.py [--model models/apg.pt] [--runs 50] [--workers 2]
        [--scenario scenarios/nominal/c_three_lane-left.yaml] [--timeout 30] [--shield]

The model is exported with ``crossroads.rl.onnx_export.export_policy_onnx`` (policy and value in one
graph) and both ``MODEL.pt`` and ``onnx:MODEL.onnx`` run the scenario's first ``--runs`` seeds in a
batch's worker processes (each episode forked, as ``crossroads evaluate`` runs them). Per seed the
outcome, the steps and the travel time are compared; the script prints the counts of both, every
seed that differs, and exits 1 if any does. ``--timeout`` shortens the episodes (seconds of ego
time) so that 2 × 50 runs take a few minutes on two cores.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path

from crossroads.evaluation.executors import EpisodeReport, EpisodeTask, ProcessExecutor, WorkerJob
from crossroads.rl.onnx_export import export_policy_onnx
from crossroads.scenario.spec import load_scenario, run_seeds

REPO = Path(__file__).resolve().parents[1]


def run_all(ref: str, spec: dict, tasks: list[EpisodeTask], workers: int) -> dict[int, EpisodeReport]:
    job = WorkerJob(spec=spec, base_dir=None, policy_ref=ref, traces="none")
    reports: list[EpisodeReport] = []
    ProcessExecutor(workers).run(job, tasks, reports.append, threading.Event())
    return {r.run_index: r for r in reports}


def summary(report: EpisodeReport) -> tuple[str, int | None, float | None]:
    if report.result is None:
        return ("error", None, None)
    return (report.result["outcome"], report.result["steps"], report.result["travel_time_s"])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, default=REPO / "models" / "apg.pt")
    parser.add_argument("--scenario", type=Path, default=REPO / "scenarios" / "nominal" / "c_three_lane-left.yaml")
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--timeout", type=float, default=30.0, help="[s] episode timeout (ego time)")
    parser.add_argument("--shield", action="store_true", help="both with the safety shield (+shield)")
    args = parser.parse_args()

    spec = load_scenario(args.scenario).model_copy(update={"timeout_s": args.timeout})
    tasks = [EpisodeTask(i, seed) for i, seed in enumerate(run_seeds(spec, args.runs))]
    suffix = "+shield" if args.shield else ""
    with tempfile.TemporaryDirectory() as tmp:
        exported = export_policy_onnx(args.model, Path(tmp) / f"{args.model.stem}.onnx")
        results = {}
        for ref in (f"{args.model}{suffix}", f"onnx:{exported}{suffix}"):
            start = time.perf_counter()
            reports = run_all(ref, spec.model_dump(mode="json"), tasks, args.workers)
            results[ref] = {i: summary(r) for i, r in reports.items()}
            counts = Counter(outcome for outcome, _, _ in results[ref].values())
            print(f"{ref}: {dict(sorted(counts.items()))} ({time.perf_counter() - start:.0f} s)")
    pt, onnx = results.values()
    differ = [i for i in sorted(pt) if pt[i] != onnx[i]]
    same = len(pt) - len(differ)
    print(f"{spec.name}, timeout {args.timeout:g} s, {len(pt)} seeds: the same outcome, steps and travel time "
          f"in {same}; differ in {len(differ)}")
    for i in differ:
        print(f"  run {i} seed {tasks[i].seed}: checkpoint {pt[i]}, onnx {onnx[i]}")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
