"""A trained run as a shippable model: the networks alone (``models/apg.pt``) and its model card.

The model file keeps the checkpoint format (so :func:`crossroads.rl.checkpoint.load_networks`
and ``--policy models/apg.pt`` read it) but only the networks and the config: no optimisers, no
replay buffer, so it is a few MB instead of the tens of MB of a training checkpoint. The card
(``models/apg.card.json``) says how the model was made: config, iterations, wall time, hardware,
the last logged losses and TAR.

A run warm-started from a shipped model (``init_from``) carries that model's history: the model file
and its card hold ``lineage``, one entry per earlier run (its iterations, wall time, changed
options), so ``iterations_total`` and ``fraction_of_paper`` count all the training behind the
weights, across sessions.
"""

from __future__ import annotations

import csv
import json
import os
import platform
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import torch

from crossroads.constants import TOTAL_ITERATIONS
from crossroads.rl.checkpoint import FORMAT, load_checkpoint
from crossroads.rl.config import TrainConfig

NETWORK_KEYS = ("policy", "value", "adversary")
# Vector extensions, which decide much of torch's CPU speed. Named on the card because the same
# 2-core run trained about 3x slower on an AVX2-only EPYC than on the host before it, which the
# card did not describe.
VECTOR_FLAGS = ("avx2", "avx512f", "avx512_bf16", "amx_tile")


def _metrics(run_dir: Path) -> list[dict[str, str]]:
    path = run_dir / "metrics.csv"
    if not path.is_file():
        return []
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def changed_from_defaults(config: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The training options of ``config`` that differ from the defaults (the paper's numbers and the
    documented choices of :class:`~crossroads.rl.config.TrainConfig`): ``{field: {"run", "default"}}``.
    Bookkeeping fields (where the run lives, logging, progress bar) are left out."""
    defaults = TrainConfig().to_json()
    skip = {"algo", "out", "run_name", "progress", "tensorboard", "checkpoint_every", "log_every", "iterations"}

    def norm(v: Any) -> Any:
        return list(v) if isinstance(v, tuple | list) else v

    return {k: {"run": norm(config[k]), "default": norm(v)} for k, v in defaults.items()
            if k in config and k not in skip and norm(config[k]) != norm(v)}


def lineage(config: dict[str, Any]) -> list[dict[str, Any]]:
    """The runs behind a warm start's initial weights, oldest first ([] for a fresh run): the init
    model's own lineage, then the init model itself (from its file and, when beside it, its card)."""
    init = config.get("init_from")
    if not init:
        return []
    init_path = Path(init)
    if not init_path.is_file():  # moved or deleted since the run started: say so, count nothing
        return [{"model": str(init_path), "algo": None, "iterations": 0, "wall_time_s": None,
                 "changed_from_defaults": {}, "missing": True}]
    model = load_checkpoint(init_path)
    card_path = init_path.with_suffix(".card.json")
    card = json.loads(card_path.read_text()) if card_path.is_file() else {}
    model_config = json.loads(model["config"]) if isinstance(model["config"], str) else model["config"]
    entry = {
        "model": str(init_path),
        "algo": model_config.get("algo"),
        "iterations": int(card.get("iterations_done", model["iteration"])),
        "wall_time_s": card.get("wall_time_s"),
        "changed_from_defaults": card.get("changed_from_defaults", changed_from_defaults(model_config)),
    }
    return [*model.get("lineage", []), entry]


def model_card(run_dir: Path, checkpoint: dict[str, Any], source: Path,
               notes: tuple[str, ...] = (), history: list[dict[str, Any]] | None = None
               ) -> dict[str, Any]:
    """What a user should know about a model: how it was trained, how far it got against the
    paper's 200 000 iterations, what differs from the defaults, and the exporter's notes."""
    # the log rows up to the checkpoint's iteration: later rows describe weights not in the file
    rows = [r for r in _metrics(run_dir) if int(r["iteration"]) <= int(checkpoint["iteration"])]
    last = rows[-1] if rows else {}
    config = json.loads(checkpoint["config"]) if isinstance(checkpoint["config"], str) else checkpoint["config"]
    wall_s = sum(float(r.get("time/elapsed_s") or 0.0) for r in rows)
    history = lineage(config) if history is None else history
    done = int(checkpoint["iteration"])
    total = done + sum(int(h["iterations"]) for h in history)
    return {
        "algo": config.get("algo"),
        "iterations_done": done,
        "iterations_planned": config.get("iterations"),
        "iterations_total": total,  # with the warm start's earlier runs (lineage)
        "paper_iterations": TOTAL_ITERATIONS,
        "fraction_of_paper": round(total / TOTAL_ITERATIONS, 4),
        "changed_from_defaults": changed_from_defaults(config),
        "notes": list(notes),
        "wall_time_s": round(wall_s, 1),
        "wall_time_total_s": round(wall_s + sum(float(h.get("wall_time_s") or 0.0) for h in history), 1),
        "lineage": history,
        "hardware": hardware(config.get("device", "cpu")),
        "final": {key: float(value) for key, value in last.items()
                  if value not in ("", None) and key != "iteration"},
        "log_rows": len(rows),
        "source_checkpoint": str(source),
        "config": config,
    }


def hardware(device: str) -> dict[str, Any]:
    """What a model card says of the machine that made it."""
    return {"machine": platform.machine(), "cpu": _cpu(), "cpus": os.cpu_count(),
            "python": platform.python_version(), "torch": torch.__version__, "device": device}


def describe_cpu(cpuinfo: str) -> str:
    """'MODEL NAME (flags…)' from the text of /proc/cpuinfo; '' when it names no model."""
    model, flags = "", set()
    for line in cpuinfo.splitlines():
        key, _, value = line.partition(":")
        if key.strip() == "model name" and not model:
            model = value.strip()
        elif key.strip() == "flags" and not flags:
            flags = set(value.split())
    if not model:
        return ""
    present = [flag for flag in VECTOR_FLAGS if flag in flags]
    return f"{model} ({', '.join(present) or 'no avx2'})"


def _cpu() -> str:
    try:
        return describe_cpu(Path("/proc/cpuinfo").read_text()) or platform.processor()
    except OSError:  # not Linux
        return platform.processor()


def export_model(run: Path, out: Path, notes: tuple[str, ...] = ()) -> tuple[Path, Path]:
    """Write ``out`` (networks + config) and ``out`` with ``.card.json`` from a run or checkpoint;
    ``notes`` (free text, e.g. what the model measured) go into the card."""
    run = Path(run)
    checkpoint = load_checkpoint(run)
    run_dir = run if run.is_dir() else run.parent.parent
    learner = checkpoint["learner"]
    config = json.loads(checkpoint["config"]) if isinstance(checkpoint["config"], str) else checkpoint["config"]
    history = lineage(config)
    model = {
        "format": FORMAT,
        "iteration": checkpoint["iteration"],
        "config": checkpoint["config"],
        "lineage": history,
        "learner": {k: learner[k] for k in NETWORK_KEYS if learner.get(k) is not None},
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".tmp")
    torch.save(model, tmp)
    tmp.replace(out)
    card_path = out.with_suffix(".card.json")
    card_path.write_text(json.dumps(model_card(run_dir, checkpoint, run, notes, history), indent=2) + "\n")
    return out, card_path


def write_refitted_model(out: Path, config: TrainConfig, nets: Sequence[torch.nn.Module | None], source: Path,
                         notes: list[str], wall_time_s: float, extra: dict[str, Any] | None = None) -> None:
    """A model fitted outside a training run from the model file ``source`` (distillation,
    imitation): ``out`` in the checkpoint format at iteration 0, with the networks ``nets``
    (policy, value, adversary or None), and its card beside it, which carries the source's lineage
    so that runs from it count all the training behind the weights. ``extra`` goes into the card
    before the config. The model file is written to a temporary name first: a half-written model
    never lands."""
    history = lineage({"init_from": str(source)})
    model = {
        "format": FORMAT,
        "iteration": 0,
        "config": config.to_json(),
        "lineage": history,
        "learner": {name: net.state_dict() for name, net in zip(("policy", "value", "adversary"), nets, strict=True)
                    if net is not None},
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".tmp")
    torch.save(model, tmp)
    tmp.replace(out)
    total = sum(int(h["iterations"]) for h in history)
    card = {
        "algo": config.algo,
        "iterations_done": 0,
        "iterations_planned": 0,
        "iterations_total": total,
        "paper_iterations": TOTAL_ITERATIONS,
        "fraction_of_paper": round(total / TOTAL_ITERATIONS, 4),
        "changed_from_defaults": changed_from_defaults(config.to_json()),
        "notes": notes,
        "wall_time_s": round(wall_time_s, 1),
        "wall_time_total_s": round(wall_time_s + sum(float(h.get("wall_time_s") or 0.0) for h in history), 1),
        "lineage": history,
        "hardware": hardware(config.device),
        **(extra or {}),
        "config": config.to_json(),
    }
    out.with_suffix(".card.json").write_text(json.dumps(card, indent=2) + "\n")
