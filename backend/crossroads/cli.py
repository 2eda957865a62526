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


def _user_errors() -> tuple[type[BaseException], ...]:
    """The error types that mean "the input is wrong", imported lazily to keep --help fast."""
    from pydantic import ValidationError

    from crossroads.network.junction import JunctionError
    from crossroads.network.resolve import NetworkNotFoundError
    from crossroads.planning import PlanningError
    from crossroads.evaluation.policies import PolicyError
    from crossroads.sim.sumo import SumoError
    from crossroads.validation import SpecError

    return (SpecError, JunctionError, NetworkNotFoundError, PlanningError, ValidationError,
            PolicyError, SumoError)


def reports_errors(func: F) -> F:
    @wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except _user_errors() as exc:
            typer.secho(f"error: {exc}", err=True, fg=typer.colors.RED)
            raise typer.Exit(code=2) from None

    return wrapper  # type: ignore[return-value]


@app.command()
@reports_errors
def serve(
    host: Annotated[str, typer.Option(help="interface to listen on")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port")] = 8000,
    db: Annotated[str | None, typer.Option(help="database URL (default: SQLite in the data dir)")] = None,
) -> None:
    """Start the studio: the API (docs at /docs) on HOST:PORT."""
    import uvicorn

    from crossroads.api.main import create_app
    from crossroads.settings import Settings

    settings = Settings(host=host, port=port, db_url=db)
    typer.echo(f"Crossroads studio on http://{host}:{port}/  (API docs: http://{host}:{port}/docs)")
    uvicorn.run(create_app(settings), host=host, port=port, log_level="info")


@net_app.command("list")
@reports_errors
def net_list() -> None:
    """The catalogue of intersections, one name a line."""
    from crossroads.network import catalogue

    for name in catalogue.list_intersections():
        typer.echo(name)


@net_app.command("build")
@reports_errors
def net_build(
    ref: Annotated[str, typer.Argument(metavar="NAME|SPEC.yaml", help="catalogue name or spec file")],
    out: Annotated[Path, typer.Option("-o", "--out", help="directory to write the .net.xml into")],
) -> None:
    """Build an intersection into a SUMO network (netconvert), cached by the spec's hash."""
    from crossroads.network import catalogue

    net = catalogue.build(Path(ref) if ref.endswith((".yaml", ".yml")) else ref)
    out.mkdir(parents=True, exist_ok=True)
    target = out / net.name
    shutil.copyfile(net, target)
    typer.echo(str(target))


@app.command()
@reports_errors
def paths(
    ref: Annotated[str, typer.Argument(metavar="NAME|NET.net.xml", help="catalogue name, spec or SUMO net")],
    task: Annotated[Task, typer.Option(help="the ego's task")],
    junction: Annotated[str | None, typer.Option(help="traffic-light junction id (default: nearest the centre)")] = None,
    approach: Annotated[str | None, typer.Option(metavar="EDGE_ID", help="incoming edge (default: from the south)")] = None,
    rho: Annotated[float, typer.Option(min=0.0, max=1.0, help="ρ of the Bezier construction")] = RHO_BEZIER,
    as_json: Annotated[bool, typer.Option("--json", help="print the candidates as JSON")] = False,
    plot: Annotated[Path | None, typer.Option(metavar="OUT.png", help="draw the intersection and candidates")] = None,
) -> None:
    """The candidate paths of a task: one per reachable target lane (Bezier, SPEC §1)."""
    from crossroads.network.resolve import open_junction
    from crossroads.planning import plan_candidates

    junc = open_junction(ref, junction)
    chosen = junc.default_approach()
    if approach is not None:
        try:
            chosen = junc.approach(approach)
        except KeyError as exc:
            typer.secho(f"error: --approach: {exc.args[0]}", err=True, fg=typer.colors.RED)
            raise typer.Exit(code=2) from None
    candidates = plan_candidates(junc, task, approach=chosen, rho=rho)
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
        typer.echo(
            f"  {c.id:<12} {c.entrance_lane} -> {c.exit_lane}  length {c.s[-1]:6.1f} m  "
            f"curve {c.s[curve][-1] - c.s[curve][0] if curve.any() else 0.0:5.1f} m  "
            f"max |curvature| {abs(c.curvature).max():.3f} 1/m"
        )
    if plot is not None:
        typer.echo(f"plot: {plot}")


@app.command()
@reports_errors
def run(
    scenario: Annotated[Path, typer.Argument(metavar="SCENARIO.yaml", help="scenario file")],
    policy: Annotated[str, typer.Option(help="'rule' or a trained checkpoint (.pt)")] = "rule",
    seed: Annotated[int | None, typer.Option(help="episode seed (default: the scenario's first run seed)")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print the result as JSON")] = False,
    trace: Annotated[Path | None, typer.Option(metavar="OUT", help="save the episode's trace (.trace.npz)")] = None,
) -> None:
    """Run one episode of a scenario and print its outcome and travel time."""
    from crossroads.evaluation.episode import run_episode
    from crossroads.evaluation.policies import load_controller
    from crossroads.evaluation.scenario import load_scenario, run_seeds, to_world_config
    from crossroads.evaluation.trace import TraceRecorder
    from crossroads.sim.world import World

    spec = load_scenario(scenario)
    controller = load_controller(policy)
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


if __name__ == "__main__":  # pragma: no cover
    app()
