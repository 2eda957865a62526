"""ONNX export of the policy (mean action) and value networks, checked against torch.

The exported graphs include the state normalisation (``network_input``), so an ONNX runtime feeds
them the raw 108-dimensional IDC state, batched: ``policy.onnx``: state (n, 108) → action (n, 2)
[Δδ rad/s, Δa m/s³]; ``value.onnx``: state (n, 108) → value (n,). Networks trained with the path
preview (``TrainConfig.path_preview``) take the 120-value preview states instead (``idc.state``).
:func:`export_policy_onnx` writes both in one graph (outputs ``action`` and ``value``), the file
``--policy onnx:PATH.onnx`` drives with (:mod:`crossroads.evaluation.onnx_policy`).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import torch
from torch import nn

from crossroads.rl.checkpoint import load_networks
from crossroads.rl.neural_nets import input_width

OPSET = 17
# Accepted difference, relative to max(1, |torch|): both run in float32 (~7 significant digits), so
# a path value in the thousands cannot agree to 1e-5 absolute, only to 1e-5 of its size.
TOLERANCE = 1e-5


class _MeanAction(nn.Module):
    """The policy's deterministic output as a plain forward (what the online decision uses)."""

    def __init__(self, policy: nn.Module) -> None:
        super().__init__()
        self.policy = policy

    def forward(self, state: torch.Tensor) -> torch.Tensor:
        return self.policy.mean_action(state)


class _PolicyAndValue(nn.Module):
    """The mean action and the path value of the same states, one graph with two outputs."""

    def __init__(self, policy: nn.Module, value: nn.Module) -> None:
        super().__init__()
        self.policy, self.value = policy, value

    def forward(self, state: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.policy.mean_action(state), self.value(state)


def _export(module: nn.Module, path: Path, output: str | tuple[str, ...], width: int) -> None:
    example = torch.zeros(2, width)
    outputs = (output,) if isinstance(output, str) else output
    # (choice) the TorchScript exporter: plain MLPs need nothing more, and it needs no onnxscript;
    # torch warns that it is deprecated in favour of the torch.export-based one
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        # the tracer's notes on the state layout checks (constant shapes: true for a fixed width)
        warnings.simplefilter("ignore", torch.jit.TracerWarning)
        torch.onnx.export(module.eval(), (example,), str(path), dynamo=False, opset_version=OPSET,
                          input_names=["state"], output_names=list(outputs),
                          dynamic_axes={"state": {0: "batch"}, **{o: {0: "batch"} for o in outputs}})


def export_onnx(model: Path, out_dir: Path) -> tuple[Path, Path]:
    """Write ``policy.onnx`` and ``value.onnx`` of a model file or checkpoint into ``out_dir``."""
    nets, _ = load_networks(model)
    out_dir.mkdir(parents=True, exist_ok=True)
    policy_path, value_path = out_dir / "policy.onnx", out_dir / "value.onnx"
    width = state_width(model)
    _export(_MeanAction(nets.policy), policy_path, "action", width)
    _export(nets.value, value_path, "value", width)
    return policy_path, value_path


def export_policy_onnx(model: Path, path: Path) -> Path:
    """Write the policy and value networks of ``model`` as one ONNX file at ``path``: state (n, width)
    → ``action`` (n, 2), ``value`` (n,); ``--policy onnx:PATH`` drives with it."""
    nets, _ = load_networks(model)
    path.parent.mkdir(parents=True, exist_ok=True)
    _export(_PolicyAndValue(nets.policy, nets.value), path, ("action", "value"), state_width(model))
    return path


def state_width(model: Path) -> int:
    """Values per state the networks of ``model`` read: 108, or 120 with the path preview."""
    _, config = load_networks(model)
    return input_width(config.path_preview)


def recorded_states(samples: int, preview: bool, seed: int = 0) -> np.ndarray:
    """``samples`` IDC states as the networks meet them online: the states of every candidate path
    at each step of seeded nominal left turns on c_three_lane driven by the rule controller (traffic
    included). Not random vectors: N(0, 1) ones put cars inside each other with negative sizes, where
    float32 rounding makes ONNX and torch differ by 1e-5 to 3e-5 of the output; on IDC states they
    agree within 4e-6 (measured on the shipped models)."""
    from crossroads.idc.rule_based import RuleBasedController
    from crossroads.idc.state import build_states, select_others
    from crossroads.intersections import catalogue
    from crossroads.sim.config import WorldConfig
    from crossroads.sim.world import World

    rows: list[np.ndarray] = []
    config = WorldConfig(net_file=catalogue.build("c_three_lane"), task="left")
    with World(config) as world:
        episode = 0
        while sum(len(r) for r in rows) < samples:
            obs, outcome = world.reset(seed + episode), None
            controller = RuleBasedController()
            controller.reset(world.candidates)
            while outcome is None and sum(len(r) for r in rows) < samples:
                decision = controller.decide(obs)
                others = select_others(obs.ego, obs.perceived.observations, obs.perceived.kinds)
                rows.append(build_states(obs.ego, others, world.candidates, decision.speed_mode, preview))
                obs, outcome = world.step(decision.action)
            episode += 1
    return np.concatenate(rows)[:samples]


def check_onnx(model: Path, policy_path: Path, value_path: Path, states: np.ndarray) -> tuple[float, float]:
    """Largest |ONNX − torch| / max(1, |torch|) of the action and of the value over ``states``."""
    import onnxruntime as ort

    nets, _ = load_networks(model)
    x = torch.as_tensor(states, dtype=torch.float32)
    with torch.no_grad():
        action, value = nets.policy.mean_action(x).numpy(), nets.value(x).numpy()
    run = {p: ort.InferenceSession(str(p), providers=["CPUExecutionProvider"])
           for p in (policy_path, value_path)}
    feed = {"state": x.numpy()}
    onnx_action = run[policy_path].run(None, feed)[0]
    onnx_value = run[value_path].run(None, feed)[0]
    def relative(a: np.ndarray, b: np.ndarray) -> float:
        return float((np.abs(a - b) / np.maximum(1.0, np.abs(b))).max())

    return relative(onnx_action, action), relative(onnx_value, value)
