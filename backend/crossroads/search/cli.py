"""``crossroads search``: search a space of scenarios for a policy's failures (mounted by
:mod:`crossroads.cli`, which turns the user's errors into one line). Imports stay inside the
command, so ``crossroads --help`` stays fast."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated, Any, Literal

import typer

from crossroads.cli_errors import fail

Sampler = Literal["tpe", "random"]
ExecutorKind = Literal["pool", "batch"]


def search(
    policy: Annotated[str | None, typer.Argument(
        metavar="POLICY", help="the policy to search failures of, as for `evaluate --policy` "
                               "(not needed with --resume)")] = None,
    space: Annotated[Path | None, typer.Option(metavar="SPACE.yaml", help="the search space file")] = None,
    budget: Annotated[int, typer.Option(min=0, help="episodes the search proposes (shrinking comes on top)")] = 200,
    workers: Annotated[int | None, typer.Option(min=1, help="episodes at once (default: CPU count)")] = None,
    ray: Annotated[str | None, typer.Option(
        metavar="ADDRESS", help="run on Ray: a cluster address, or 'local' to start a local Ray")] = None,
    db: Annotated[str | None, typer.Option(help="database URL (default: SQLite in the data dir)")] = None,
    seed: Annotated[int, typer.Option(min=0, help="the search's seed (sampler and episode seeds)")] = 0,
    sampler: Annotated[Sampler, typer.Option(
        help="tpe: optuna's TPE on the near-miss objective; random: uniform (a baseline)")] = "tpe",
    generation: Annotated[int | None, typer.Option(
        min=1, help="trials proposed without each other's results: trial n knows the results of "
                    "trials 0..n-N (default: the workers); fixes the search's sequence")] = None,
    shrink_steps: Annotated[int | None, typer.Option(
        min=0, help="at most this many episodes to shrink each failure (default: 2 per parameter)")] = None,
    failures_dir: Annotated[Path | None, typer.Option(
        metavar="DIR", help="where the failures go as scenario files (default: <data dir>/failures/...)")] = None,
    shrink_limit: Annotated[int | None, typer.Option(
        min=0, help="shrink only the first N distinct failures; the rest are kept as found (default: all)")] = None,
    executor: Annotated[ExecutorKind, typer.Option(
        help="pool: long-lived search workers, one forked episode per trial; batch: a fresh batch "
             "worker process per trial (slower; as before). Ray (--ray) always uses its actors")] = "pool",
    resume: Annotated[int | None, typer.Option(metavar="SEARCH_ID", help="resume a stored search instead")] = None,
    report: Annotated[Path | None, typer.Option(
        metavar="OUT.html", help="also write the search's report (outcome against each parameter)")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the summary as JSON")] = False,
) -> None:
    """Search scenario space for POLICY's failures: shrink each one and keep it as a scenario file."""
    _search(policy, space, budget, workers, ray, db, seed, sampler, generation, shrink_steps,
            shrink_limit, failures_dir, resume, report, as_json, executor)


def _search(policy: str | None, space_file: Path | None, budget: int, workers: int | None,
            ray: str | None, db: str | None, seed: int, sampler: str, generation: int | None,
            shrink_steps: int | None, shrink_limit: int | None, failures_dir: Path | None,
            resume: int | None, report: Path | None, as_json: bool, executor: str = "pool") -> None:
    import os

    from tqdm import tqdm

    from crossroads.policy.identity import policy_identity
    from crossroads.search.engine import SearchRunner, create_search_for
    from crossroads.search.space import load_space, network_problems_of
    from crossroads.settings import Settings
    from crossroads.store import open_store
    from crossroads.validation import SpecError

    if resume is None and (policy is None or space_file is None):
        raise fail("give POLICY and --space SPACE.yaml (or --resume SEARCH_ID)")
    settings = Settings(db_url=db, ray_address=ray)
    workers = workers or os.cpu_count() or 1
    store = open_store(settings.database_url)
    try:
        if resume is None:
            assert policy is not None and space_file is not None
            space = load_space(space_file)
            if problems := network_problems_of(space):
                raise SpecError(str(space_file), problems)
            policy_identity(policy)  # a missing or unreadable policy fails here, before any row
            search_id = create_search_for(store, space=space, policy=policy, budget=budget,
                                          sampler=sampler, seed=seed,
                                          generation=generation or workers,
                                          shrink_steps=shrink_steps, failures_dir=failures_dir)
        else:
            search_id = resume
        with tqdm(desc=f"search {search_id}", unit="ep", disable=None, leave=False) as bar:
            def progress(p: Any) -> None:
                bar.total = p.budget
                bar.n = p.searched
                bar.set_postfix_str(f"failing {p.failing}, failures {p.failures}/{p.to_shrink or '?'}, "
                                    f"shrink episodes {p.shrink_episodes}", refresh=False)
                bar.refresh()

            runner = SearchRunner(store, search_id, workers=workers, ray_address=settings.ray_address,
                                  data_dir=settings.data_dir, on_progress=progress,
                                  shrink_limit=shrink_limit, executor=executor)
            try:
                summary = runner.run()
            except KeyboardInterrupt:
                typer.secho(f"interrupted: resume with `crossroads search --resume {search_id}`"
                            + (f" --db {db}" if db else ""), err=True, fg=typer.colors.YELLOW)
                raise typer.Exit(code=130) from None
        if report is not None:
            from crossroads.search.report import write_report

            write_report(store, search_id, report)
    finally:
        store.close()
    if as_json:
        json.dump(summary, sys.stdout)
        sys.stdout.write("\n")
    else:
        for line in summary_lines(summary):
            typer.echo(line)
    if report is not None:
        typer.echo(f"report: {report}", err=as_json)  # stdout keeps the JSON alone


def summary_lines(s: dict[str, Any]) -> list[str]:
    """The summary for a person: the figures, then one line per failure."""
    outcomes = ", ".join(f"{k} {v}" for k, v in sorted(s["outcomes"].items())) or "none"
    best = "n/a" if s["best_objective"] is None else f"{s['best_objective']:.3f}"
    lines = [
        f"search {s['search_id']}: {s['name']} x {s['policy']} [{s['status']}], sampler {s['sampler']}, "
        f"seed {s['seed']}: {s['searched']}/{s['budget']} episodes ({outcomes}); best objective {best}",
        f"failing episodes {s['failing']}; failures kept {s['failures']} ({s['distinct_failures']} distinct, "
        f"{s['failure_modes']} modes) after {s['shrink_episodes']} shrinking episodes; in {s['failures_dir']}",
    ]
    for f in s["failure_list"]:
        moved = ", ".join(f"{k}={f['params'][k]:g}" for k in f["off_nominal"]) or "nominal"
        lines.append(f"  {f['outcome']:9s} seed {f['seed']:>7d}  distance {f['distance']:.3f}  {moved}  "
                     f"-> {Path(f['yaml_path']).name if f['yaml_path'] else '-'}")
    return lines
