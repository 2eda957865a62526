"""The ``crossroads`` command.

Every command turns the project's own errors (a bad spec, a missing net, a junction it cannot
read, an impossible task) into one clear line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import json
import shutil
import sys
from collections.abc import Callable
from functools import wraps
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

import typer

from crossroads.cli_errors import describe, fail
from crossroads.constants import RHO_BEZIER

app = typer.Typer(
    help="Crossroads: test driving policies at signalized intersections (IDC + APG).",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)
net_app = typer.Typer(help="The intersection catalogue and SUMO network builds.", no_args_is_help=True)
app.add_typer(net_app, name="net")


def _mount_training() -> None:
    """`crossroads train ...`: APG/DPG training (crossroads.rl.cli)."""
    from crossroads.rl.cli import app as train_app

    app.add_typer(train_app, name="train")


_mount_training()

F = TypeVar("F", bound=Callable[..., Any])
Task = Literal["left", "straight", "right"]
POLICY_HELP = ("'rule', a trained checkpoint (PATH.pt), onnx:PATH.onnx or py:package.module:Factory "
               "(+shield after a checkpoint or ONNX file: with the safety shield)")


def _user_errors() -> tuple[type[BaseException], ...]:
    """The error types that mean "the input is wrong", imported lazily to keep --help fast."""
    from pydantic import ValidationError

    from crossroads.evaluation.batch import BatchError
    from crossroads.evaluation.executors import ExecutorError
    from crossroads.evaluation.stored_batches import UnknownBatchError
    from crossroads.intersections.resolve import NetworkNotFoundError
    from crossroads.network.junction import JunctionError
    from crossroads.planning import PlanningError
    from crossroads.policy.ref import PolicyError
    from crossroads.search.engine import SearchError
    from crossroads.sim.sumo import SumoError
    from crossroads.store import StoreError
    from crossroads.validation import SpecError

    return (SpecError, JunctionError, NetworkNotFoundError, PlanningError, ValidationError,
            PolicyError, SumoError, StoreError, UnknownBatchError, BatchError, ExecutorError, SearchError)


def reports_errors(func: F) -> F:
    @wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except _user_errors() as exc:
            raise fail(describe(exc)) from None

    return wrapper  # type: ignore[return-value]


def _mount_search() -> None:
    """`crossroads search ...`: a policy's failures searched for in scenario space (crossroads.search.cli)."""
    from crossroads.search.cli import search

    app.command()(reports_errors(search))


_mount_search()


@app.command()
@reports_errors
def serve(
    host: Annotated[str, typer.Option(help="interface to listen on")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port")] = 8000,
    db: Annotated[str | None, typer.Option(help="database URL (default: SQLite in the data dir)")] = None,
    ray: Annotated[str | None, typer.Option(help="Ray cluster address for batches (default: local workers)")] = None,
    max_batches: Annotated[int | None, typer.Option(
        help="batches run at once; more wait in a queue (default 2)")] = None,
    resume_batches: Annotated[bool | None, typer.Option(
        "--resume-batches/--no-resume-batches",
        help="resume batches a previous run of the studio left queued or running (default: yes)")] = None,
    token: Annotated[str | None, typer.Option(
        help="access token requests must carry (default: CROSSROADS_TOKEN; generated when the host is "
             "not a loopback address)")] = None,
    allowed_host: Annotated[list[str] | None, typer.Option(
        "--allowed-host", help="a host name the studio answers to besides localhost and HOST (repeat; "
                               "'*' for any)")] = None,
) -> None:
    """Start the studio: the API (docs at /docs) on HOST:PORT."""
    import secrets

    import uvicorn

    from crossroads.api.main import create_app
    from crossroads.settings import WILDCARD_HOSTS, Settings, is_loopback

    # options not given keep the CROSSROADS_* environment or the defaults
    given = {"ray_address": ray, "max_concurrent_batches": max_batches, "resume_batches": resume_batches,
             "token": token, "allowed_hosts": allowed_host}
    options = {k: v for k, v in given.items() if v is not None}
    settings = Settings(host=host, port=port, db_url=db, **options)
    if settings.public and settings.token is None:  # beyond loopback, never without a token
        settings = Settings(host=host, port=port, db_url=db, **{**options, "token": secrets.token_urlsafe(24)})
    shown = f"[{host}]" if ":" in host else host
    url = f"http://{shown}:{port}/"
    if settings.token is not None:
        url += f"?token={settings.token.get_secret_value()}"
    if not is_loopback(host):
        names = ", ".join(sorted(settings.answered_hosts()))
        if host in WILDCARD_HOSTS:
            names += " and this machine's own names and addresses"
        typer.echo(f"WARNING: listening on {host}: any machine that reaches this one on port {port} can reach "
                   "the studio. Every API request needs the access token in the URL below; the 3D viewers "
                   "(viser, each on a port of its own) do not ask for it and listen there too. "
                   f"The studio answers to the host names {names} (add more with --allowed-host).", err=True)
    typer.echo(f"Crossroads studio on {url}  (API docs: http://{shown}:{port}/docs)")
    # open event streams and viewer sockets never close by themselves: after 5 s they are cut, so
    # the app's shutdown runs (its batches marked interrupted) before a service manager kills it
    uvicorn.run(create_app(settings), host=host, port=port, log_level="info", timeout_graceful_shutdown=5)


@net_app.command("list")
@reports_errors
def net_list() -> None:
    """The catalogue of intersections, one name a line."""
    from crossroads.intersections import catalogue

    for name in catalogue.list_intersections():
        typer.echo(name)


@net_app.command("build")
@reports_errors
def net_build(
    ref: Annotated[str, typer.Argument(metavar="NAME|SPEC.yaml", help="catalogue name or spec file")],
    out: Annotated[Path, typer.Option("-o", "--out", help="directory to write the .net.xml into")],
) -> None:
    """Build an intersection into a SUMO network (netconvert), cached by the spec's hash."""
    from crossroads.intersections import catalogue

    source = Path(ref) if ref.endswith((".yaml", ".yml")) else ref
    spec = catalogue.load_spec(source)
    net = catalogue.build(source)
    out.mkdir(parents=True, exist_ok=True)
    target = out / f"{spec.name}.net.xml"
    shutil.copyfile(net, target)
    typer.echo(str(target))


@net_app.command("check")
@reports_errors
def net_check(
    ref: Annotated[str, typer.Argument(metavar="NAME|NET.net.xml", help="catalogue name, spec or SUMO net")],
    junction: Annotated[str | None, typer.Option(help="traffic-light junction id (default: nearest the centre)")] = None,
    max_offset: Annotated[float | None, typer.Option(
        metavar="M", min=0.0, help="exit with status 1 when the internal lane of a task movement (left, "
                                   "straight, right; U-turns are not judged) runs further than M metres "
                                   "from its candidate path (default: only report)")] = None,
    rho: Annotated[float | None, typer.Option(
        min=0.0, max=1.0, help=f"ρ of the Bezier construction (the paper: {RHO_BEZIER}; "
                               "default: chosen per path within the ego's steering limit)")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the movements as JSON")] = False,
) -> None:
    """How far SUMO's internal lanes run from the candidate paths, movement by movement.

    SUMO's vehicles drive the internal lanes and SUMO puts the ego where it projects onto them;
    the ego drives its candidate path. Movements further apart than half the ego's width are
    marked. The catalogue's builds draw the internal lanes along the paths.
    """
    from crossroads.constants import INTERNAL_LANE_OFFSET_WARN_M
    from crossroads.intersections.resolve import open_junction
    from crossroads.planning.internal_lanes import internal_lane_offsets, worst_offset

    junc = open_junction(ref, junction)
    offsets = internal_lane_offsets(junc, rho=rho)
    worst = worst_offset(offsets)
    if as_json:
        json.dump([o.to_json() for o in offsets], sys.stdout)
        sys.stdout.write("\n")
    else:
        typer.echo(f"junction {junc.id} (tl {junc.tl_id}): {len(offsets)} car movements; "
                   f"max = farthest apart, mean = mean distance of the path from SUMO's lane; "
                   f"! above {INTERNAL_LANE_OFFSET_WARN_M:g} m")
        for o in offsets:
            figures = (f"max {o.max_m:5.2f} m  mean {o.mean_m:5.2f} m" if o.max_m is not None and o.mean_m is not None
                       else o.problem)
            judged = "" if o.is_task else " (not a task: not judged)"
            typer.echo(f"{'!' if o.above_warning else ' '} {o.from_lane} -> {o.to_lane} ({o.turn}, "
                       f"via {o.via_lane or '-'}): {figures}{judged}")
        above = sum(o.above_warning for o in offsets)
        typer.echo(f"{above} of {len(offsets)} movements above {INTERNAL_LANE_OFFSET_WARN_M:g} m"
                   + (f"; the farthest {worst.max_m:.2f} m" if worst is not None else ""))
    if max_offset is not None and worst is not None and worst.max_m is not None and worst.max_m > max_offset:
        typer.secho(f"{worst.from_lane} -> {worst.to_lane}: SUMO's internal lane runs up to "
                    f"{worst.max_m:.2f} m from its candidate path, above --max-offset {max_offset:g}",
                    err=True, fg=typer.colors.RED)
        raise typer.Exit(code=1)


@app.command()
@reports_errors
def paths(
    ref: Annotated[str, typer.Argument(metavar="NAME|NET.net.xml", help="catalogue name, spec or SUMO net")],
    task: Annotated[Task, typer.Option(help="the ego's task")],
    junction: Annotated[str | None, typer.Option(help="traffic-light junction id (default: nearest the centre)")] = None,
    approach: Annotated[str | None, typer.Option(metavar="EDGE_ID", help="incoming edge (default: from the south)")] = None,
    rho: Annotated[float | None, typer.Option(
        min=0.0, max=1.0, help=f"ρ of the Bezier construction for every path (the paper: {RHO_BEZIER}; "
                               "default: chosen per path within the ego's steering limit)")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the candidates as JSON")] = False,
    plot: Annotated[Path | None, typer.Option(metavar="OUT.png", help="draw the intersection and candidates")] = None,
) -> None:
    """The candidate paths of a task: one per reachable target lane (Bezier, SPEC §1)."""
    from crossroads.intersections.resolve import open_junction
    from crossroads.planning import plan_task

    junc = open_junction(ref, junction)
    chosen = junc.default_approach()
    if approach is not None:
        try:
            chosen = junc.approach(approach)
        except KeyError as exc:
            raise fail(f"--approach: {exc.args[0]}") from None
    plan = plan_task(junc, task, approach=chosen, rho=rho)
    candidates = plan.require()  # none: one line saying why (reports_errors)
    for warning in plan.warnings:
        typer.secho(f"warning: {warning}", err=True, fg=typer.colors.YELLOW)
    if plot is not None:
        from crossroads.viz.figure import save_intersection_figure

        save_intersection_figure(junc, candidates, plot, title=f"{ref}: {task}")
    if as_json:
        json.dump([c.to_json() for c in candidates], sys.stdout)
        sys.stdout.write("\n")
        return
    typer.echo(f"junction {junc.id} (tl {junc.tl_id}), approach {chosen.id}, task {task}: "
               f"{len(candidates)} candidate(s)")
    for c in candidates:
        curve = c.segment == "curve"
        moved = (f"  X1 back {c.x1_shift_m:g} m, X4 on {c.x4_shift_m:g} m"
                 if c.x1_shift_m or c.x4_shift_m else "")
        typer.echo(
            f"  {c.id:<12} {c.entrance_lane} -> {c.exit_lane}  length {c.s[-1]:6.1f} m  "
            f"curve {c.s[curve][-1] - c.s[curve][0] if curve.any() else 0.0:5.1f} m  "
            f"rho {c.rho:.2f}  max curvature {c.max_curvature:.3f} 1/m{'!' if c.exceeds_limit else ''}{moved}"
        )
    if plot is not None:
        typer.echo(f"plot: {plot}")


@app.command()
@reports_errors
def run(
    scenario: Annotated[Path, typer.Argument(metavar="SCENARIO.yaml", help="scenario file")],
    policy: Annotated[str, typer.Option(help=POLICY_HELP)] = "rule",
    seed: Annotated[int | None, typer.Option(help="episode seed (default: the scenario's first run seed)")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the result as JSON")] = False,
    trace: Annotated[Path | None, typer.Option(metavar="OUT", help="save the episode's trace (.trace.npz)")] = None,
) -> None:
    """Run one episode of a scenario and print its outcome and travel time."""
    from crossroads.evaluation.episode import run_episode
    from crossroads.evaluation.policies import load_controller
    from crossroads.evaluation.trace import TraceRecorder
    from crossroads.policy.ref import parse_policy
    from crossroads.scenario.network_checks import internal_lane_warning, network_problems
    from crossroads.scenario.spec import load_scenario, run_seeds, to_world_config
    from crossroads.sim.world import World
    from crossroads.validation import SpecError

    spec = load_scenario(scenario)
    if problems := network_problems(spec, scenario.parent):  # as evaluate and the API check it
        raise SpecError(str(scenario), problems)
    controller = load_controller(parse_policy(policy))
    if warning := internal_lane_warning(spec, scenario.parent):
        typer.secho(f"warning: {scenario}: {warning}", err=True, fg=typer.colors.YELLOW)
    episode_seed = run_seeds(spec, 1)[0] if seed is None else seed
    recorder = TraceRecorder() if trace is not None else None
    with World(to_world_config(spec, base_dir=scenario.parent)) as world:
        result = run_episode(world, controller, episode_seed, recorder=recorder,
                             scenario_name=spec.name)
    if recorder is not None:
        recorder.trace().save(trace)
    if as_json:
        json.dump({"scenario": spec.name, "policy": policy, **result.to_json()}, sys.stdout)
        sys.stdout.write("\n")
        return
    travel = "" if result.travel_time_s is None else f", travel time {result.travel_time_s:.2f} s"
    detail = f" ({result.detail})" if result.detail else ""
    typer.echo(f"{spec.name} seed {episode_seed}: {result.outcome}{detail}{travel}, "
               f"{result.steps} steps ({result.time_s:.1f} s)")
    if trace is not None:
        typer.echo(f"trace: {trace}")


@app.command("export")
@reports_errors
def export_command(
    scenario: Annotated[Path, typer.Argument(metavar="SCENARIO.yaml", help="scenario file")],
    out: Annotated[Path, typer.Option("-o", "--out", metavar="DIR", help="directory to write the bundle into")],
    seed: Annotated[int | None, typer.Option(
        min=0, max=2**31 - 1, help="episode seed (default: the scenario's first run seed)")] = None,
) -> None:
    """Write one episode's SUMO bundle (net, seeded routes, additionals, .sumocfg) for sumo-gui."""
    from crossroads.evaluation.sumo_bundle import export_bundle
    from crossroads.scenario.spec import load_scenario, run_seeds

    spec = load_scenario(scenario)
    episode_seed = run_seeds(spec, 1)[0] if seed is None else seed
    bundle = export_bundle(spec, episode_seed, out, base_dir=scenario.parent)
    for path in bundle.files():
        typer.echo(str(path))
    typer.echo(f"seed {episode_seed}: sumo-gui -c {bundle.config}")


TraceOption = Literal["all", "failed", "none"]


@app.command()
@reports_errors
def evaluate(
    scenario: Annotated[Path | None, typer.Argument(
        metavar="SCENARIO.yaml|DIR", help="scenario file, or a directory of them")] = None,
    policy: Annotated[list[str] | None, typer.Option(
        help=POLICY_HELP + "; repeat to compare policies on the same seeds")] = None,
    runs: Annotated[int | None, typer.Option(min=1, help="runs per batch (default: the scenario's runs)")] = None,
    workers: Annotated[int | None, typer.Option(min=1, help="worker processes (default: CPU count)")] = None,
    ray: Annotated[str | None, typer.Option(
        metavar="ADDRESS", help="run on Ray: a cluster address, or 'local' to start a local Ray")] = None,
    db: Annotated[str | None, typer.Option(help="database URL (default: SQLite in the data dir)")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print one JSON object per batch (a list)")] = False,
    traces: Annotated[TraceOption, typer.Option(help="save the traces of all, failed or no episodes")] = "failed",
    resume: Annotated[list[int] | None, typer.Option(
        metavar="BATCH_ID", help="resume stored batches instead (runs already recorded are skipped)")] = None,
) -> None:
    """Run batches (one per scenario x policy) into the results store and print their figures."""
    from tqdm import tqdm

    from crossroads.evaluation.batch import BatchRunner, create_batch_for
    from crossroads.scenario.network_checks import batch_warnings, network_problems
    from crossroads.scenario.spec import load_scenarios
    from crossroads.settings import Settings
    from crossroads.store import open_store
    from crossroads.validation import SpecError

    if scenario is None and not resume:
        raise fail("give a SCENARIO.yaml or DIR (or --resume BATCH_ID)")
    settings = Settings(db_url=db, ray_address=ray)
    store = open_store(settings.database_url)
    # Every scenario file is validated before anything runs; each batch is created just before
    # it runs, so an interrupted command leaves no queued batches behind, only the one to resume.
    planned: list[Callable[[], int]] = [lambda b=b: b for b in resume or []]
    if scenario is not None:
        found = load_scenarios(scenario)
        if not found:
            raise fail(f"no scenario files (*.yaml) in {scenario}")
        warned: list[list[str]] = []
        for path, spec in found:  # what only the network can tell, before any batch starts
            if problems := network_problems(spec, path.parent):
                raise SpecError(str(path), problems)
            warned.append(batch_warnings(spec, path.parent))  # measured once: printed and stored
            for warning in warned[-1]:
                typer.secho(f"warning: {path}: {warning}", err=True, fg=typer.colors.YELLOW)
        for (path, spec), warnings in zip(found, warned, strict=True):
            for ref in policy or ["rule"]:
                planned.append(lambda spec=spec, ref=ref, base=path.parent, warnings=warnings: create_batch_for(
                    store, spec=spec, policy=ref, runs=runs, traces=traces, base_dir=base, warnings=warnings))
    results = []
    try:
        for plan in planned:
            batch_id = plan()
            with tqdm(desc=f"batch {batch_id}", unit="ep", disable=None, leave=False) as bar:
                def progress(done: int, total: int, last: Any, bar: Any = bar, batch_id: int = batch_id) -> None:
                    bar.total = total
                    bar.n = done
                    if last is not None and last.outcome == "error":
                        bar.write(f"batch {batch_id} run {last.run_index}: error: "
                                  f"{(last.error or '').splitlines()[0]}", file=sys.stderr)
                    bar.refresh()

                runner = BatchRunner(store, batch_id, workers=workers, ray_address=settings.ray_address,
                                     data_dir=settings.data_dir, on_progress=progress)
                try:
                    result = runner.run()
                except KeyboardInterrupt:
                    typer.secho(f"interrupted: resume with `crossroads evaluate --resume {batch_id}`"
                                + (f" --db {db}" if db else ""), err=True, fg=typer.colors.YELLOW)
                    raise typer.Exit(code=130) from None
            results.append(result)
            if not as_json:
                typer.echo(_batch_line(result))
    finally:
        store.close()
    if as_json:
        json.dump([r.to_json() for r in results], sys.stdout)
        sys.stdout.write("\n")


def _batch_line(r: Any) -> str:
    """One batch's figures on one line (for `evaluate`)."""
    rate = ("n/a" if r.pass_rate is None else
            f"{100 * r.pass_rate:.1f} % ({r.passed}/{r.judged}), "
            f"Wilson 95 % [{100 * r.wilson_low:.1f}, {100 * r.wilson_high:.1f}] %")
    travel = "n/a" if r.travel_time_mean_s is None else (
        f"{r.travel_time_mean_s:.2f} ± {r.travel_time_std_s or 0.0:.2f} s")
    outcomes = ", ".join(f"{k} {v}" for k, v in r.outcome_counts.items() if v)
    if getattr(r, "blocked", 0):
        outcomes += f" (blocked by the world: {r.blocked})"
    return (f"batch {r.batch_id}: {r.scenario} x {r.policy} [{r.status}]: pass rate {rate}; "
            f"errors {r.errors}; outcomes: {outcomes or 'none'}; travel time {travel}")

@app.command()
@reports_errors
def report(
    batch_ids: Annotated[list[int], typer.Argument(metavar="BATCH_ID...", help="stored batches")],
    out: Annotated[Path, typer.Option("-o", "--out", metavar="OUT.html", help="the HTML report")],
    csv: Annotated[Path | None, typer.Option(metavar="OUT.csv", help="also one CSV line per batch")] = None,
    markdown: Annotated[Path | None, typer.Option(
        metavar="OUT.md", help="also the main table as Markdown (ours beside the paper's)")] = None,
    db: Annotated[str | None, typer.Option(help="database URL (default: SQLite in the data dir)")] = None,
    title: Annotated[str, typer.Option(help="the report's title")] = "Crossroads evaluation",
) -> None:
    """Tables like the paper's (with its numbers beside), plots and failed episodes' traces."""
    from crossroads.evaluation.report import render_html, write_csv
    from crossroads.evaluation.stored_batches import report_rows
    from crossroads.settings import Settings
    from crossroads.store import open_store

    store = open_store(Settings(db_url=db).database_url)
    try:
        rows = report_rows(store, batch_ids)
    finally:
        store.close()
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(render_html(rows, title=title), encoding="utf-8")
    typer.echo(f"report: {out}")
    if csv is not None:
        write_csv(rows, csv)
        typer.echo(f"csv: {csv}")
    if markdown is not None:
        from crossroads.evaluation.report_markdown import render_markdown

        markdown.write_text(render_markdown(rows), encoding="utf-8")
        typer.echo(f"markdown: {markdown}")


@app.command()
@reports_errors
def view(
    traces: Annotated[list[Path], typer.Argument(metavar="TRACE.npz...", help="stored episode traces")],
    host: Annotated[str, typer.Option(help="interface to listen on")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port (0: any free port)")] = 8080,
    net: Annotated[str | None, typer.Option(metavar="NAME|NET.net.xml",
                                            help="network to draw (default: the trace's own)")] = None,
    autoplay: Annotated[bool, typer.Option(help="start playing when a tab opens")] = False,
) -> None:
    """Play stored episodes in the 3D view (viser); every browser tab gets its own player."""
    import time

    from crossroads.viz.playback import PlaybackServer

    for trace in traces:
        if not trace.is_file():
            raise fail(f"trace {str(trace)!r} does not exist")
    app_ = PlaybackServer(traces, host=host, port=port, net=net, autoplay=autoplay)
    typer.echo(f"Crossroads 3D view on {app_.url}  ({len(traces)} episode(s); Ctrl-C to stop)")
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        app_.stop()


if __name__ == "__main__":  # pragma: no cover
    app()
