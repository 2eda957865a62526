"""Failure search against uniform random sampling of the same space, the same episode budget.

    python benchmarks/failure_search.py --budget 1000            # the issue's figure
    nice -n 5 python benchmarks/failure_search.py --budget 200 --workers 3 --timeout 60 --seed 41 \
        --shrink-limit 1 --shrink-steps 6 --work-dir var/failure-search   # docs/guide/failure-search.md

Two searches of one space for one policy (default ``models/apg.pt+shield`` on
``scenarios/search/c_three_lane-left.yaml``), each through the real ``crossroads search`` command
with the same budget, seed, workers and shrinking: one with optuna's TPE on the near-miss
objective, one with optuna's uniform random sampler. Then every failure each stored is replayed
with ``crossroads evaluate`` on its scenario file (a fresh store) and its outcome compared.

Figures: distinct failing scenarios per 1 000 search episodes (distinct: the stored failure's
scenario, its name left out; shrinking episodes are not counted in the budget and are reported
apart), their ratio (target: TPE at least 3× random), failure modes (outcome and the parameters a
shrunk failure still needs off nominal), and two counts that near-copies of one failure (the same
region, another seed) cannot inflate: the cells of the space (each range in thirds) that hold a
failure, and the failures at least 10 % (20 %) of some parameter's range apart from every failure
counted before them (``separated_failures``); the failing share with its Wilson 95 % interval and
a one-sided Fisher exact test of TPE's failing share against random's; and how many stored
failures replay with the same outcome (target: all).

``--timeout S`` replaces the nominal scenario's episode timeout (the space is rewritten with the
scenario inline): shorter episodes, the same failures before S. Exit status 1 when a target is
missed.

``--throughput N`` measures instead how fast trials run, side by side: the same search (uniform
random sampler, N trials, the same seed, so the same points and scenario seeds) once with
``--executor batch`` (a fresh batch worker process per trial, as searches ran before the pool) and
once with ``--executor pool`` (the search's long-lived workers), each through the real command;
trials per minute of each, and whether every trial ended the same in both, field for field
(outcome, steps, times, near-miss figures): the batch worker runs a trial exactly as
``crossroads evaluate`` runs its scenario file.

    nice -n 10 python benchmarks/failure_search.py --throughput 16 --workers 2 --timeout 60 --seed 41
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

REPO_ROOT = Path(__file__).resolve().parents[1]
TARGET_RATIO = 3.0
CELL_BINS = 3  # a range cut in this many parts for failing_cells


def crossroads(*args: str, env: dict[str, str]) -> dict[str, Any] | list[Any]:
    """Run the real command; its JSON output (the last line)."""
    done = subprocess.run([sys.executable, "-m", "crossroads.cli", *args], capture_output=True,
                          text=True, cwd=REPO_ROOT, env=env)
    if done.returncode != 0:
        raise SystemExit(f"crossroads {' '.join(args)} failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def space_file(space: Path, timeout: float | None, work: Path) -> Path:
    """The space, with the nominal scenario inline and its timeout replaced when asked."""
    if timeout is None:
        return space
    from crossroads.search.space import load_space

    loaded = load_space(space)
    data = loaded.to_json()
    data["scenario"]["timeout_s"] = timeout
    out = work / f"{space.stem}-timeout{timeout:g}.yaml"
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return out


def replay(failures_dir: Path, policy: str, out_dir: Path, workers: int, env: dict[str, str]) -> dict[str, str]:
    """``crossroads evaluate`` on every failure file of a search: scenario name → outcome. The files
    are dealt to ``workers`` commands run side by side (each file is a batch of one run, and one
    command runs its batches one after the other), each with its own store in ``out_dir``."""
    files = sorted(failures_dir.glob("*.yaml"))
    groups = [files[k::workers] for k in range(workers) if files[k::workers]]
    procs = []
    for k, group in enumerate(groups):
        folder = out_dir / f"{failures_dir.name}-{k}"
        folder.mkdir(parents=True, exist_ok=True)
        for path in group:
            (folder / path.name).unlink(missing_ok=True)
            (folder / path.name).symlink_to(path.resolve())
        db = f"sqlite:///{out_dir / f'{failures_dir.name}-{k}.db'}"
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "crossroads.cli", "evaluate", str(folder), "--policy", policy, "--db", db,
             "--workers", "1", "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            cwd=REPO_ROOT, env=env))
    out = {}
    for proc in procs:
        stdout, stderr = proc.communicate()
        if proc.returncode != 0:
            raise SystemExit(f"crossroads evaluate failed ({proc.returncode}):\n{stderr[-3000:]}")
        for batch in json.loads(stdout.strip().splitlines()[-1]):
            counts = {k: v for k, v in batch["outcome_counts"].items() if v}
            out[batch["scenario"]] = next(iter(counts)) if len(counts) == 1 else json.dumps(counts)
    return out


def stored_arms(db: str) -> dict[str, dict[str, Any]]:
    """The summaries of the newest search of each sampler in the store (for --recount)."""
    from crossroads.search import records
    from crossroads.search.engine import summarize_search
    from crossroads.store import open_store

    store = open_store(db)
    try:
        with store.session() as session:
            newest = {s.sampler: s.id for s in reversed(records.list_searches(session=session))}
        return {sampler: summarize_search(store, newest[sampler]) for sampler in ("tpe", "random")}
    finally:
        store.close()


def stored_replays(out_dir: Path) -> dict[str, str]:
    """Scenario name → outcome of every replayed failure in the replay stores (for --recount)."""
    from crossroads.evaluation.batch import summarize_batch
    from crossroads.store import crud, open_store

    out = {}
    for path in sorted(out_dir.glob("*.db")):
        store = open_store(f"sqlite:///{path}")
        try:
            with store.session() as session:
                ids = [b.id for b in crud.list_batches(session=session, limit=100_000)]
            for batch_id in ids:
                result = summarize_batch(store, batch_id)
                counts = {k: v for k, v in result.outcome_counts.items() if v}
                out[result.scenario] = next(iter(counts)) if len(counts) == 1 else json.dumps(counts)
        finally:
            store.close()
    return out


def failing_points(db: str, search_id: int) -> tuple[Any, list[dict[str, Any]]]:
    """(the search's space, the params of its failing search episodes in trial order), read once."""
    from crossroads.search import records
    from crossroads.search.engine import stored_space
    from crossroads.search.objective import FAILURE_VALUE
    from crossroads.store import open_store

    store = open_store(db)
    try:
        with store.session() as session:
            search = records.get_search(session=session, search_id=search_id)
            assert search is not None
            space = stored_space(search.space, search_id)
            failing = [t.params for t in records.trials(session=session, search_id=search_id, kind="search")
                       if t.objective == FAILURE_VALUE]
    finally:
        store.close()
    return space, failing


def failing_cells(space: Any, failing: list[dict[str, Any]], bins: int = CELL_BINS) -> int:
    """How many cells of the space hold a failing episode (:func:`failing_points`), each range cut
    in ``bins`` equal parts (each choice a part of its own): a count of distinct failures that
    near-copies of one failure cannot inflate."""
    cells = set()
    for params in failing:
        cell = []
        for p in space.parameters:
            value = float(params[p.path])
            if p.choices is not None:
                cell.append(value)
            else:
                part = (value - float(p.low)) / (float(p.high) - float(p.low))  # type: ignore[arg-type]
                cell.append(min(int(part * bins), bins - 1))
        cells.add(tuple(cell))
    return len(cells)


def stored_trials(db: str) -> dict[int, dict[str, Any]]:
    """Trial number → params, seed, result of the (only) search in a store."""
    from crossroads.search import records
    from crossroads.store import open_store

    store = open_store(db)
    try:
        with store.session() as session:
            (search,) = records.list_searches(session=session)
            return {t.number: {"params": t.params, "seed": t.seed, "result": t.result}
                    for t in records.trials(session=session, search_id=search.id, kind="search")}
    finally:
        store.close()


def throughput(args: argparse.Namespace, space: Path, work: Path, env: dict[str, str]) -> int:
    """The same random search with a batch worker per trial, then on the pool: trials per minute
    of each, and whether each trial ended the same."""
    figures: dict[str, Any] = {"policy": args.policy, "space": str(args.space), "trials": args.throughput,
                               "workers": args.workers, "seed": args.seed, "timeout_s": args.timeout,
                               "load_average": list(os.getloadavg()), "executors": {}}
    trials: dict[str, dict[int, dict[str, Any]]] = {}
    for executor in ("batch", "pool"):
        db = f"sqlite:///{work / f'throughput-{executor}.db'}"
        start = time.perf_counter()
        summary = crossroads("search", args.policy, "--space", str(space), "--budget", str(args.throughput),
                             "--workers", str(args.workers), "--seed", str(args.seed), "--sampler", "random",
                             "--executor", executor, "--shrink-limit", "0", "--db", db,
                             "--failures-dir", str(work / f"throughput-failures-{executor}"), "--json", env=env)
        wall = time.perf_counter() - start
        assert isinstance(summary, dict)
        trials[executor] = stored_trials(db)
        steps = sum((t["result"] or {}).get("steps") or 0 for t in trials[executor].values())
        figures["executors"][executor] = {
            "wall_s": round(wall, 1), "trials_per_min": round(60.0 * summary["searched"] / wall, 2),
            "steps": steps, "ms_per_step": round(1000.0 * wall / steps, 2) if steps else None,
            "outcomes": summary["outcomes"]}
        print(f"{executor}: {summary['searched']} trials in {wall:.1f} s = "
              f"{figures['executors'][executor]['trials_per_min']} trials/min ({summary['outcomes']})", flush=True)
    batch, pool = trials["batch"], trials["pool"]
    same_points = batch.keys() == pool.keys() and all(
        batch[n]["params"] == pool[n]["params"] and batch[n]["seed"] == pool[n]["seed"] for n in batch)
    differ = [n for n in batch if batch[n]["result"] != pool.get(n, {}).get("result")]
    figures["same_points"] = same_points
    figures["same_results"] = len(batch) - len(differ)
    figures["results_differ"] = {n: (batch[n]["result"], pool.get(n, {}).get("result")) for n in differ}
    speedup = figures["executors"]["batch"]["wall_s"] / figures["executors"]["pool"]["wall_s"]
    figures["speedup"] = round(speedup, 2)
    print(json.dumps(figures, indent=2))
    if args.out is not None:
        args.out.write_text(json.dumps(figures, indent=2) + "\n")
    print(f"trials per minute: batch worker per trial {figures['executors']['batch']['trials_per_min']}, "
          f"pool {figures['executors']['pool']['trials_per_min']} ({speedup:.2f}x); the same trials: "
          f"{same_points}; the same results: {figures['same_results']} of {len(batch)}", flush=True)
    return 0 if same_points and not differ else 1


def separated_failures(space: Any, failing: list[dict[str, Any]], radius: float) -> int:
    """How many failing episodes (:func:`failing_points`) are at least ``radius`` apart: taken in
    trial order, a failure counts when every one counted before differs from it by ``radius`` or
    more of some parameter's range (or in a choice). Near-copies of one failure (the same region,
    another seed) count once; ``failing_cells`` is the same idea on a fixed grid."""
    kept: list[dict[str, Any]] = []
    for params in failing:
        def apart(other: dict[str, Any], params: dict[str, Any] = params) -> bool:
            for p in space.parameters:
                a, b = float(params[p.path]), float(other[p.path])
                if (a != b) if p.choices is not None else abs(a - b) >= radius * p.span:
                    return True
            return False
        if all(apart(other) for other in kept):
            kept.append(params)
    return len(kept)


def fisher_greater(a: int, n: int, b: int, m: int) -> float:
    """One-sided Fisher exact test: the chance of ``a`` or more of the ``a + b`` failures falling in
    the first arm (``n`` episodes; the second ``m``) were both arms the same."""
    total, k = n + m, a + b
    return sum(math.comb(n, i) * math.comb(m, k - i) for i in range(a, min(n, k) + 1)) / math.comb(total, k)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", default="models/apg.pt+shield")
    parser.add_argument("--space", type=Path, default=REPO_ROOT / "scenarios/search/c_three_lane-left.yaml")
    parser.add_argument("--budget", type=int, default=1000, help="search episodes per arm")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--seed", type=int, default=41, help="the searches' seed (the scenario seeds are drawn from it)")
    parser.add_argument("--executor", choices=("pool", "batch"), default="pool",
                        help="where the searches' trials run (crossroads search --executor)")
    parser.add_argument("--throughput", type=int, default=None, metavar="N",
                        help="measure trials per minute instead: N random trials with each executor")
    parser.add_argument("--timeout", type=float, default=None, help="episode timeout [s] (default: the scenario's)")
    parser.add_argument("--shrink-steps", type=int, default=None, help="per failure (default: 2 per parameter)")
    parser.add_argument("--shrink-limit", type=int, default=None, help="shrink the first N failures of each arm")
    parser.add_argument("--work-dir", type=Path, default=None, help="store, failures, reports (default: a temp dir)")
    parser.add_argument("--out", type=Path, default=None, help="also write the figures as JSON")
    parser.add_argument("--recount", action="store_true",
                        help="run nothing: the figures of the searches and replays stored in --work-dir")
    args = parser.parse_args()
    from crossroads.evaluation.metrics import wilson_interval
    if args.recount and args.work_dir is None:
        parser.error("--recount needs --work-dir")

    work = args.work_dir or Path(tempfile.mkdtemp(prefix="failure-search-"))
    work.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "CROSSROADS_DATA_DIR": str(work / "data")}
    space = space_file(args.space.resolve(), args.timeout, work)
    if args.throughput is not None:
        return throughput(args, space, work, env)
    db = f"sqlite:///{work / 'search.db'}"
    arms: dict[str, dict[str, Any]] = stored_arms(db) if args.recount else {}
    for sampler in () if args.recount else ("tpe", "random"):
        start = time.perf_counter()
        command = ["search", args.policy, "--space", str(space), "--budget", str(args.budget),
                   "--workers", str(args.workers), "--seed", str(args.seed), "--sampler", sampler,
                   "--executor", args.executor,
                   "--db", db, "--failures-dir", str(work / f"failures-{sampler}"),
                   "--report", str(work / f"report-{sampler}.html"), "--json"]
        if args.shrink_steps is not None:
            command += ["--shrink-steps", str(args.shrink_steps)]
        if args.shrink_limit is not None:
            command += ["--shrink-limit", str(args.shrink_limit)]
        summary = crossroads(*command, env=env)
        assert isinstance(summary, dict)
        summary["wall_s"] = round(time.perf_counter() - start, 1)
        arms[sampler] = summary
        print(f"{sampler}: {summary['searched']} episodes, outcomes {summary['outcomes']}, "
              f"{summary['distinct_failures']} distinct failures, {summary['failure_modes']} modes, "
              f"{summary['shrink_episodes']} shrinking episodes, {summary['wall_s']} s", flush=True)

    replay_dir = work / "replay"
    figures: dict[str, Any] = {"policy": args.policy, "space": str(args.space), "budget": args.budget,
                               "seed": args.seed, "timeout_s": args.timeout, "work_dir": str(work), "arms": {}}
    all_replayed = True
    for sampler, summary in arms.items():
        replayed = (stored_replays(replay_dir) if args.recount
                    else replay(work / f"failures-{sampler}", args.policy, replay_dir, args.workers, env))
        stored = {f["name"]: f["outcome"] for f in summary["failure_list"]}
        same = sum(replayed.get(name) == outcome for name, outcome in stored.items())
        differ = {name: (outcome, replayed.get(name)) for name, outcome in stored.items()
                  if replayed.get(name) != outcome}
        all_replayed &= not differ
        per_1000 = 1000.0 * summary["distinct_failures"] / summary["searched"] if summary["searched"] else 0.0
        space, failing = failing_points(db, summary["search_id"])
        cells = failing_cells(space, failing)
        low, high = wilson_interval(summary["failing"], summary["searched"])
        figures["arms"][sampler] = {
            "episodes": summary["searched"], "outcomes": summary["outcomes"],
            "failing_episodes": summary["failing"],
            "failing_share_wilson95": [round(low, 3), round(high, 3)],
            "distinct_failures": summary["distinct_failures"],
            "distinct_per_1000": round(per_1000, 1), "failure_modes": summary["failure_modes"],
            "failing_cells": cells,
            "separated_10pct": separated_failures(space, failing, 0.1),
            "separated_20pct": separated_failures(space, failing, 0.2),
            "cells_per_1000": round(1000.0 * cells / summary["searched"], 1) if summary["searched"] else 0.0,
            "shrink_episodes": summary["shrink_episodes"], "replayed_same": same,
            "stored": len(stored), "replay_differs": differ, "wall_s": summary.get("wall_s")}
    tpe, rnd = figures["arms"]["tpe"]["distinct_per_1000"], figures["arms"]["random"]["distinct_per_1000"]
    ratio = tpe / rnd if rnd else float("inf") if tpe else None
    figures["ratio"] = None if ratio is None else round(ratio, 2)
    t_arm, r_arm = figures["arms"]["tpe"], figures["arms"]["random"]
    figures["cells_ratio"] = (round(t_arm["cells_per_1000"] / r_arm["cells_per_1000"], 2)
                              if r_arm["cells_per_1000"] else None)
    for key in ("separated_10pct", "separated_20pct"):  # the budgets are the same: a ratio of counts
        figures[f"{key}_ratio"] = round(t_arm[key] / r_arm[key], 2) if r_arm[key] else None
    figures["fisher_one_sided_p"] = round(fisher_greater(
        t_arm["failing_episodes"], t_arm["episodes"], r_arm["failing_episodes"], r_arm["episodes"]), 5)
    print(json.dumps(figures, indent=2))
    if args.out is not None:
        args.out.write_text(json.dumps(figures, indent=2) + "\n")
    ok = all_replayed and ratio is not None and ratio >= TARGET_RATIO
    print(f"distinct failing scenarios per 1000 episodes: TPE {tpe}, random {rnd}, ratio "
          f"{figures['ratio']} (target >= {TARGET_RATIO:g}); failing cells per 1000: ratio "
          f"{figures['cells_ratio']}; failures 10 % apart: ratio {figures['separated_10pct_ratio']}; "
          f"every stored failure replays the same: {all_replayed}", flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
