"""Checkpoints: everything a run needs to continue exactly, in one ``torch.save`` file.

Contents: format version, the config (JSON), the iteration (iterations done), the learner's networks,
optimisers and schedulers, RNG states (python, numpy global, torch), the replay buffer (contents,
position, generator), the sampler's bookkeeping (next round, the round in flight and the policy
weights it was issued with), the path keys, and the running metric sums of the current log window.
``checkpoints/ckpt_<iteration>.pt`` and ``checkpoints/last.pt`` (a copy of the newest).

Files are read with ``torch.load(weights_only=True)``: only tensors and plain data (dicts, lists,
tuples, strings, numbers) come back, so a file can never run code when it is opened (a checkpoint
path given to a batch is loaded again on every resume). What is not plain data is stored as such:
numpy arrays go in as tensors under a ``{"__ndarray__": tensor}`` marker and come back as arrays.
A file written by an older Crossroads that pickled numpy arrays directly is refused with a message;
:func:`convert_legacy` (``python -m crossroads.rl.checkpoint convert FILE``) rewrites one you trust.

:func:`load_networks` rebuilds the networks of a checkpoint for inference (``crossroads.rl.load_policy``).
"""

from __future__ import annotations

import argparse
import pickle
import random
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from crossroads.rl.config import TrainConfig
from crossroads.rl.neural_nets import Networks, networks_for

FORMAT = 1
LAST = "last.pt"
NDARRAY = "__ndarray__"  # marker key of a numpy array stored as a tensor


class UnsafeCheckpointError(ValueError):
    """The file holds objects beyond tensors and plain data (an older format, or a foreign file)."""


def rng_states() -> dict[str, Any]:
    return {"python": random.getstate(), "numpy": np.random.get_state(), "torch": torch.get_rng_state()}


def set_rng_states(state: dict[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    torch.set_rng_state(state["torch"])


def to_plain(value: Any) -> Any:
    """``value`` with every numpy array as ``{NDARRAY: tensor}`` and every numpy scalar as a Python
    number: what ``torch.load(weights_only=True)`` reads back. Containers holding neither are
    returned as they are (a state_dict keeps its type and metadata)."""
    if isinstance(value, np.ndarray):
        if value.dtype.hasobject:
            raise TypeError("numpy arrays of Python objects cannot be stored in a checkpoint")
        return {NDARRAY: torch.from_numpy(np.ascontiguousarray(value).copy())}
    if isinstance(value, np.generic):
        return value.item()
    return _map(value, to_plain)


def from_plain(value: Any) -> Any:
    """The inverse of :func:`to_plain`."""
    if isinstance(value, dict) and len(value) == 1 and isinstance(value.get(NDARRAY), torch.Tensor):
        return value[NDARRAY].numpy()
    return _map(value, from_plain)


def _map(value: Any, convert: Any) -> Any:
    """``convert`` applied inside a dict, list or tuple; the container itself when nothing changed."""
    if isinstance(value, Mapping):
        items = {k: convert(v) for k, v in value.items()}
        return value if all(items[k] is v for k, v in value.items()) else items
    if isinstance(value, list | tuple):
        converted = [convert(v) for v in value]
        if all(c is v for c, v in zip(converted, value, strict=True)):
            return value
        return converted if isinstance(value, list) else tuple(converted)
    return value


def save_checkpoint(run_dir: Path, iteration: int, payload: dict[str, Any]) -> Path:
    folder = Path(run_dir) / "checkpoints"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"ckpt_{iteration:08d}.pt"
    tmp = path.with_suffix(".tmp")
    torch.save(to_plain({"format": FORMAT, "iteration": iteration, **payload}), tmp)
    tmp.replace(path)
    shutil.copyfile(path, folder / LAST)
    return path


def find_checkpoint(path: Path) -> Path:
    """A checkpoint file, or the newest of a run directory / its checkpoints folder."""
    path = Path(path)
    if path.is_file():
        return path
    for folder in (path / "checkpoints", path):
        if (folder / LAST).is_file():
            return folder / LAST
    raise FileNotFoundError(f"no checkpoint at {path}")


def load_checkpoint(path: Path, map_location: str | torch.device = "cpu") -> dict[str, Any]:
    """A checkpoint's contents, read without running anything from the file (``weights_only``)."""
    file = find_checkpoint(path)
    try:
        data = torch.load(file, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as exc:
        raise UnsafeCheckpointError(
            f"{file}: holds objects beyond tensors and plain data, so it is not loaded (loading it "
            "could run code from the file). A checkpoint of an older Crossroads that you trust can be "
            f"rewritten with: python -m crossroads.rl.checkpoint convert {file}") from exc
    if not isinstance(data, dict):
        raise ValueError(f"{file}: not a Crossroads checkpoint (a {type(data).__name__})")
    if data.get("format") != FORMAT:
        raise ValueError(f"{path}: checkpoint format {data.get('format')!r}, expected {FORMAT}")
    return from_plain(data)


def convert_legacy(source: Path, target: Path | None = None) -> Path:
    """Rewrite a checkpoint of an older Crossroads (numpy arrays pickled directly) in the plain
    format; ``target`` defaults to ``source`` (replaced atomically). This unpickles the file in
    full, which can run code from it: only for files you trust."""
    source = find_checkpoint(source)
    target = source if target is None else Path(target)
    data = torch.load(source, map_location="cpu", weights_only=False)  # noqa: S614 - the user vouches for it
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{source}: not a Crossroads checkpoint of format {FORMAT}")
    tmp = target.with_suffix(".tmp")
    torch.save(to_plain(data), tmp)
    tmp.replace(target)
    return target


def load_networks(path: Path, device: str | torch.device = "cpu") -> tuple[Networks, TrainConfig]:
    """The networks of a checkpoint (eval mode) and its config."""
    data = load_checkpoint(path, device)
    config = TrainConfig.from_json(data["config"])
    nets = networks_for(config, device)
    learner = data["learner"]
    nets.policy.load_state_dict(learner["policy"])
    nets.value.load_state_dict(learner["value"])
    if nets.adversary is not None:
        nets.adversary.load_state_dict(learner["adversary"])
    for net in nets:
        if net is not None:
            net.eval()
    return nets, config


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m crossroads.rl.checkpoint",
                                     description="Checkpoint maintenance.")
    commands = parser.add_subparsers(dest="command", required=True)
    convert = commands.add_parser("convert", help="rewrite an older checkpoint you trust in the plain format")
    convert.add_argument("file", type=Path)
    convert.add_argument("-o", "--out", type=Path, default=None, help="write here (default: in place)")
    args = parser.parse_args(argv)
    print(convert_legacy(args.file, args.out))


if __name__ == "__main__":
    main()
