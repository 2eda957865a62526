"""``crossroads train``: the typer sub-app of training (mounted by the main CLI as ``train``).

    crossroads train --algo apg|dpg [--iterations N] [--workers K] [--ray ADDRESS] [--out DIR]
                     [--seed S] [--resume] [--experiment NAME ...] [--set KEY=VALUE ...]
    crossroads train plot RUN_DIR [RUN_DIR ...] -o OUT.png
    crossroads train options          # every TrainConfig field with its meaning
    crossroads train experiments      # the named experiments (rl.experiments)
    crossroads train distill MODEL.pt -o OUT.pt --set participant_encoder=64   # a new network layout

Without ``--experiment`` or ``--set`` a run has the paper's configuration (``TrainConfig()``).
``--experiment NAME`` applies a named recipe (:mod:`crossroads.rl.experiments`), several in the
order given; ``--set`` then reaches any :class:`~crossroads.rl.config.TrainConfig` field
(``--set batch_size=8 --set tasks=left,straight``) and has the last word. Imports of torch happen
only when a command runs.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from crossroads.cli_errors import fail

app = typer.Typer(help="Train the IDC networks by APG (adversarial) or DPG (baseline).",
                  invoke_without_command=True, pretty_exceptions_enable=False)


@app.callback()
def train_command(
    ctx: typer.Context,
    algo: Annotated[str, typer.Option(help="apg (with adversary) or dpg (ξ ≡ 0)")] = "apg",
    iterations: Annotated[Optional[int], typer.Option(help="iterations (paper: 200000)")] = None,
    workers: Annotated[Optional[int], typer.Option(help="sampling processes (0: in-process)")] = None,
    ray: Annotated[Optional[str], typer.Option("--ray", help="Ray cluster address for the workers")] = None,
    out: Annotated[Optional[Path], typer.Option(help="parent directory of the run directory")] = None,
    seed: Annotated[Optional[int], typer.Option(help="the run's seed")] = None,
    resume: Annotated[bool, typer.Option(help="continue the run's newest checkpoint")] = False,
    experiment: Annotated[Optional[list[str]], typer.Option(
        "--experiment", metavar="NAME",
        help="a named experiment (crossroads train experiments); repeatable, applied in order before --set")] = None,
    set_: Annotated[Optional[list[str]], typer.Option("--set", help="KEY=VALUE of any TrainConfig field")] = None,
) -> None:
    """Train (without a sub-command). No --experiment and no --set: the paper's configuration."""
    if ctx.invoked_subcommand is not None:
        return
    from crossroads.rl.config import TrainConfig, apply_overrides, parse_overrides
    from crossroads.rl.experiments import apply_experiments
    from crossroads.rl.train import RunExistsError, train

    overrides: dict[str, object] = {"algo": algo}
    for key, value in (("iterations", iterations), ("workers", workers), ("ray_address", ray),
                       ("out", out), ("seed", seed)):
        if value is not None:
            overrides[key] = value
    try:
        overrides.update(parse_overrides(set_ or []))
        config = apply_overrides(apply_experiments(TrainConfig(), experiment or []), overrides)
        run_dir = train(config, resume=resume)
    except (ValueError, RunExistsError, FileNotFoundError) as exc:
        raise fail(str(exc)) from None
    typer.echo(str(run_dir))


@app.command("options")
def options_command() -> None:
    """List every training option with its default and meaning."""
    import dataclasses

    from crossroads.rl.config import TrainConfig, field_docs

    docs = field_docs()
    for f in dataclasses.fields(TrainConfig):
        typer.echo(f"{f.name} = {getattr(TrainConfig(), f.name)!r}\n    {docs.get(f.name, '')}")


@app.command("experiments")
def experiments_command() -> None:
    """List the named experiments: what each sets, what for, and where its result is written."""
    from crossroads.rl.experiments import EXPERIMENTS

    for experiment in EXPERIMENTS.values():
        values = " ".join(f"{key}={value}" for key, value in experiment.overrides.items())
        typer.echo(f"{experiment.name}\n    {experiment.description}\n    sets: {values}\n"
                   f"    measured: {experiment.measured}")


PANELS: tuple[tuple[str, str], ...] = (
    ("losses/J_pi", "J_π (policy cost)"), ("losses/J_v", "J_v (value loss)"),
    ("losses/J_track", "J_track"), ("losses/J_safe", "J_safe"), ("charts/TAR", "TAR"),
)


def plot_runs(run_dirs: list[Path], output: Path) -> Path:
    """Curves like the paper's Fig. 4-5 (one line per run, TAR with a ±std band) into ``output``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from crossroads.rl.logging import read_metrics

    fig, axes = plt.subplots(2, 3, figsize=(13, 7))
    flat = axes.ravel()
    for run in run_dirs:
        m = read_metrics(run)
        label = Path(run).name
        for ax, (key, title) in zip(flat, PANELS):
            ax.plot(m["iteration"], m[key], label=label)
            if key == "charts/TAR":
                lo = [a - s for a, s in zip(m[key], m["charts/TAR_std"])]
                hi = [a + s for a, s in zip(m[key], m["charts/TAR_std"])]
                ax.fill_between(m["iteration"], lo, hi, alpha=0.2)
            ax.set_title(title)
            ax.set_xlabel("iteration")
            if key != "charts/TAR" and all(v > 0 for v in m[key] if not math.isnan(v)):
                ax.set_yscale("log")
        flat[5].plot(m["iteration"], m["charts/lr_policy"], label=f"{label} policy")
        flat[5].plot(m["iteration"], m["charts/lr_value"], label=f"{label} value")
    flat[5].set_title("learning rates")
    flat[5].set_xlabel("iteration")
    for ax in flat:
        ax.grid(alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=7)
    fig.tight_layout()
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=120)
    plt.close(fig)
    return output


@app.command("plot")
def plot_command(
    run_dirs: Annotated[list[Path], typer.Argument(help="run directories (each with metrics.csv)")],
    output: Annotated[Path, typer.Option("-o", "--output", help="image file to write (.png, .pdf)")],
) -> None:
    """Training curves (J_π, J_v, J_track, J_safe, TAR) of one or more runs."""
    for run in run_dirs:
        if not (Path(run) / "metrics.csv").is_file():
            raise fail(f"{run} has no metrics.csv")
    typer.echo(str(plot_runs(list(run_dirs), output)))


@app.command("export")
def export_command(
    run: Annotated[Path, typer.Argument(metavar="RUN_DIR|CHECKPOINT", help="a training run or checkpoint")],
    out: Annotated[Path, typer.Option("-o", "--out", metavar="MODEL.pt", help="e.g. models/apg.pt")],
    note: Annotated[list[str] | None, typer.Option(
        help="a line for the card's notes, e.g. what the model measured (repeatable)")] = None,
) -> None:
    """Ship a run's networks as MODEL.pt with its model card (MODEL.card.json)."""
    from crossroads.rl.export import export_model

    try:
        model, card = export_model(run, out, tuple(note or ()))
    except (FileNotFoundError, ValueError) as exc:
        raise fail(str(exc)) from None
    typer.echo(f"model: {model} ({model.stat().st_size / 1e6:.1f} MB)\ncard: {card}")


@app.command("distill")
def distill_command(
    model: Annotated[Path, typer.Argument(metavar="MODEL.pt", help="the source: a model file or checkpoint")],
    out: Annotated[Path, typer.Option("-o", "--out", metavar="OUT.pt", help="the distilled model file")],
    set_: Annotated[list[str], typer.Option("--set", help="KEY=VALUE: the new layout (e.g. participant_encoder=64)")],
    episodes: Annotated[int, typer.Option(help="seeded sampling episodes the states come from (a tenth held out)")] = 200,
    steps: Annotated[int, typer.Option(help="Adam steps of the fit")] = 4000,
    seed: Annotated[int, typer.Option(help="seed of the episodes, the new networks and the batches")] = 0,
) -> None:
    """Refit a model's driving policy and value network in another layout (then --set init_from=OUT.pt)."""
    from crossroads.rl.config import parse_overrides
    from crossroads.rl.distill import distill

    try:
        report = distill(model, out, parse_overrides(set_), episodes=episodes, steps=steps, seed=seed)
    except (FileNotFoundError, ValueError) as exc:
        raise fail(str(exc)) from None
    typer.echo("\n".join([f"model: {out}", *report.lines()]))


@app.command("onnx")
def onnx_command(
    model: Annotated[Path, typer.Argument(metavar="MODEL.pt", help="a model file or checkpoint")],
    out: Annotated[Path, typer.Option("-o", "--out", metavar="DIR",
                                      help="where policy.onnx, value.onnx and MODEL.onnx (both in one) go")],
    samples: Annotated[int, typer.Option(help="IDC states (of seeded rule-driven left turns in traffic) the export is checked on")] = 512,
) -> None:
    """Export the policy and value networks to ONNX and check them against torch (within 1e-5);
    MODEL.onnx holds both, for ``--policy onnx:DIR/MODEL.onnx``."""
    from crossroads.rl.checkpoint import load_networks
    from crossroads.rl.onnx_export import TOLERANCE, check_onnx, export_onnx, export_policy_onnx, recorded_states

    try:
        policy_path, value_path = export_onnx(model, out)
        combined = export_policy_onnx(model, out / f"{model.stem}.onnx")
    except (FileNotFoundError, ValueError) as exc:
        raise fail(str(exc)) from None
    states = recorded_states(samples, load_networks(model)[1].path_preview)
    action_err, value_err = check_onnx(model, policy_path, value_path, states)
    typer.echo(f"{policy_path}\n{value_path}\n{combined} (--policy onnx:{combined})\n"
               f"max |onnx - torch| / max(1, |torch|) on {samples} states: "
               f"action {action_err:.2e}, value {value_err:.2e}")
    if max(action_err, value_err) > TOLERANCE:
        raise fail(f"ONNX differs from torch by more than {TOLERANCE:g}", code=1)

