"""Does the world flow? SUMO's own driver, the rule controller and the traffic, measured.

    .venv/bin/python benchmarks/world_flow.py [--runs 200] [--base-seed 20261206] \
        [--policy sumo --policy rule] [--scenario scenarios/nominal/c_three_lane-left.yaml ...] \
        [--flow-window 900] [--per-lane] [--workers 2] [--json OUT.json]

Three measurements of the world as built (sim/gridlock.py, the signal program of
intersections/build.py, the demand of sim/traffic.py), on seeds drawn from ``--base-seed`` (not the
scenarios' own base seed 0, so that nothing here was tuned on the seeds it reports):

1. per scenario (default: the 18 nominal and the 6 paper scenarios) and policy (default: ``sumo``,
   SUMO's own driver, and ``rule``): outcomes of ``--runs`` seeded episodes with the scenario's
   timeout, the pass rate with its Wilson interval, the runs *blocked by the world* (a timeout
   behind a participant that barred every candidate path the whole episode: sim/blocking.py)
   and the participants the gridlock breaker removed per episode;
2. per intersection: the flow that crossed the junction per entrance lane and hour, per kind,
   against the demand (sim/flow.py), over ``--flow-window`` seconds after the warm-up; with
   ``--per-lane``, each entrance lane's demand, flow, green and queues (sim/lane_flow.py), which
   tell a lane held at its head from one whose green cannot carry its demand;
3. targets: SUMO's driver ≥ 98 % on every nominal scenario with 0 collisions; blocked runs ≤ 1
   per scenario; the rule controller ≥ 90 % on the nominal left turn of c_three_lane and ≥ 95 % on
   every nominal straight and right turn; every flow within 10 % of its demand.

The episodes run in the batch workers of ``crossroads evaluate`` (evaluation/executors.py), each in
a child forked from its worker: SUMO's result can depend on the memory it runs in, so a seed run
after other episodes in one process can end otherwise than the same seed run first. Run this way,
every episode here is the one ``crossroads evaluate SCENARIO --seed BASE --runs N --policy P``
gives for that run.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import threading
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

from crossroads.evaluation.executors import EpisodeReport, EpisodeTask, ProcessExecutor, WorkerJob  # noqa: E402
from crossroads.evaluation.metrics import wilson_interval  # noqa: E402
from crossroads.evaluation.sumo_driver import SUMO_POLICY  # noqa: E402
from crossroads.network.junction import read_junction  # noqa: E402
from crossroads.scenario.spec import load_scenario, run_seeds, to_world_config  # noqa: E402
from crossroads.sim.flow import measure_flow  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_SCENARIOS = sorted((ROOT / "scenarios" / "nominal").glob("*.yaml")) + sorted(
    (ROOT / "scenarios" / "paper").glob("*.yaml"))
DEFAULT_BASE_SEED = 20261206  # differs from the scenarios' own base seed (0)


def _episodes(path: Path, policy: str, seeds: list[int], workers: int) -> list[dict[str, object]]:
    """Run one scenario's seeds with one policy in ``workers`` batch workers (module docstring);
    one row per seed, in the seeds' order (an episode that raised: outcome ``error``)."""
    spec = load_scenario(path)
    job = WorkerJob(spec=spec.model_dump(mode="json"), base_dir=str(path.parent), policy_ref=policy,
                    traces="none")
    reports: dict[int, EpisodeReport] = {}
    ProcessExecutor(workers).run(job, [EpisodeTask(i, seed) for i, seed in enumerate(seeds)],
                                 lambda r: reports.__setitem__(r.run_index, r), threading.Event())
    out = []
    for i, seed in enumerate(seeds):
        report = reports[i]
        r = report.result or {}
        out.append({"seed": seed, "outcome": report.outcome, "time_s": r.get("time_s"),
                    "travel_time_s": r.get("travel_time_s"), "blocked_by": r.get("blocked_by"),
                    "removed": sum(1 for e in r.get("events", ()) if e["event"] == "gridlock_removed"),
                    "detail": r["detail"] if report.result else str(report.error).splitlines()[0]})
    return out


def _flow(task: tuple[str, int, float, bool]) -> dict[str, object]:
    path, seed, window, per_lane = task
    spec = load_scenario(Path(path))
    cfg = to_world_config(spec, Path(path).parent)
    junction = read_junction(cfg.net_file, cfg.junction_id)
    with tempfile.TemporaryDirectory() as tmp:
        report = measure_flow(junction, cfg.demand, Path(tmp), seed=seed, warmup_s=cfg.warmup_s,
                              window_s=window, gridlock_stand_s=cfg.gridlock_stand_s,
                              junction_clearing=cfg.junction_clearing, let_out=cfg.let_out,
                              junction_lane_changes=cfg.junction_lane_changes, per_lane=per_lane)
    return {"intersection": str(spec.intersection), "kinds": [
        {"kind": k.kind, "demand": k.demand_per_lane_h, "crossed": k.crossed_per_lane_h,
         "removed": k.removed} for k in report.kinds],
        "lanes": [{"lane": f.lane, "turns": list(f.turns), "demand": f.demand_h, "crossed": f.crossed_h,
                   "green_share": f.green_share, "queued_discharge": f.queued_discharge_h,
                   "greens": f.greens, "greens_ending_queued": f.greens_ending_queued}
                  for f in report.lanes]}


def _print_lanes(flow: dict[str, Any]) -> None:
    """One intersection's per-lane table (sim/lane_flow.py)."""
    print(f"  {flow['intersection']}: {'lane':14} {'turns':22} {'demand':>6} {'crossed':>7} {'green':>5} "
          f"{'queued discharge':>16} {'greens leaving a queue':>22}")
    for f in flow["lanes"]:
        print(f"  {'':{len(str(flow['intersection']))}}  {f['lane']:14} {','.join(f['turns']):22} "
              f"{f['demand']:6.0f} {f['crossed']:7.0f} {f['green_share']:5.2f} {f['queued_discharge']:16.0f} "
              f"{f['greens_ending_queued']:>15} of {f['greens']:<3}")


def _report(path: str, policy: str, eps: list[dict[str, object]]) -> bool:
    """Print one scenario × policy row; whether it meets its targets."""
    c = Counter(str(e["outcome"]) for e in eps)
    n = len(eps)
    lo, hi = wilson_interval(c["passed"], n)
    blocked = sum(1 for e in eps if e["blocked_by"])
    removed = sum(int(e["removed"]) for e in eps) / max(n, 1)
    name = Path(path).stem
    print(f"{Path(path).parent.name + '/' + name:38} {policy:6} {c['passed']:>3}/{n:<3} "
          f"[{100 * lo:5.1f},{100 * hi:5.1f}] {c['collision']:>4} {c['red_light']:>3} "
          f"{c['off_road']:>3} {c['timeout']:>3} {blocked:>7} {removed:>10.2f}", flush=True)
    rate = c["passed"] / max(n, 1)
    nominal = Path(path).parent.name == "nominal"
    if policy == SUMO_POLICY and nominal and (rate < 0.98 or c["collision"] > 0):
        return False
    if blocked > 1:
        return False
    return not (policy == "rule" and nominal and (
        (name == "c_three_lane-left" and rate < 0.90)
        or (name.endswith(("-straight", "-right")) and rate < 0.95)))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--base-seed", type=int, default=DEFAULT_BASE_SEED)
    parser.add_argument("--policy", action="append", default=[])
    parser.add_argument("--scenario", action="append", type=Path, default=[])
    parser.add_argument("--flow-window", type=float, default=900.0, help="[s]; 0 skips the flow")
    parser.add_argument("--per-lane", action="store_true",
                        help="also each entrance lane's demand, flow, green and queues (veh/h)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    policies = args.policy or [SUMO_POLICY, "rule"]
    scenarios = args.scenario or DEFAULT_SCENARIOS
    results: dict[tuple[str, str], list[dict[str, object]]] = {}
    ok = True
    print(f"base seed {args.base_seed}, {args.runs} runs per scenario and policy", flush=True)
    print(f"{'scenario':38} {'policy':6} {'passed':>7} {'95 % CI':>15} {'coll':>4} {'red':>3} "
          f"{'off':>3} {'tmo':>3} {'blocked':>7} {'removed/ep':>10}", flush=True)
    if args.runs > 0:
        for path in scenarios:
            seeds = run_seeds(load_scenario(path).model_copy(update={"seed": args.base_seed}), args.runs)
            for policy in policies:
                results[(str(path), policy)] = _episodes(path, policy, seeds, args.workers)
                ok &= _report(str(path), policy, results[(str(path), policy)])
    flows = []
    if args.flow_window > 0:
        by_intersection = {}
        for path in scenarios:
            by_intersection.setdefault(str(load_scenario(path).intersection), path)
        flow_tasks = [(str(p), args.base_seed, args.flow_window, args.per_lane)
                      for p in by_intersection.values()]
        with ProcessPoolExecutor(args.workers) as pool:
            flows = list(pool.map(_flow, flow_tasks))
    if flows:
        print(f"\nflow over {args.flow_window:g} s after the warm-up, per entrance lane and hour "
              "(crossed / demand; removed by the gridlock breaker)")
        for f in flows:
            cells = []
            for k in f["kinds"]:
                ratio = k["crossed"] / k["demand"] if k["demand"] else float("nan")
                cells.append(f"{k['kind']} {k['crossed']:.0f}/{k['demand']:.0f} ({100 * ratio:.0f} %, "
                             f"removed {k['removed']})")
                if k["demand"] and abs(ratio - 1.0) > 0.10:
                    ok = False
            print(f"  {f['intersection']:20} " + "; ".join(cells))
        if args.per_lane:
            print("\nper entrance lane (vehicles per hour; green: share of the window its main movement had it; "
                  "queued discharge: per hour of green while 2 or more stood on it; greens leaving "
                  "3 or more standing)")
            for f in flows:
                _print_lanes(f)
    nominal = any(Path(path).parent.name == "nominal" for path in scenarios)
    checked = [text for applies, text in (
        (SUMO_POLICY in policies and nominal, "SUMO's driver >= 98 % of every nominal scenario, no collision"),
        (True, "at most 1 blocked run per scenario"),
        ("rule" in policies and nominal, "the rule controller >= 90 % (c_three_lane left), >= 95 % (straight, right)"),
        (bool(flows), "every flow within 10 % of its demand")) if applies]
    print(f"\ntargets {'met' if ok else 'NOT met'} ({'; '.join(checked)})")
    if args.json:
        args.json.write_text(json.dumps({"base_seed": args.base_seed, "runs": args.runs,
                                         "episodes": {f"{Path(p).stem}|{pol}": e for (p, pol), e in results.items()},
                                         "flows": flows}, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
