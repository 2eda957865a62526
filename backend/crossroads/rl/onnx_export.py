"""ONNX export of the policy (mean action) and value networks, checked against torch.

The exported graphs include the state normalisation (``network_input``), so an ONNX runtime feeds
them the raw 108-dimensional IDC state, batched: ``policy.onnx``: state (n, 108) → action (n, 2)
[Δδ rad/s, Δa m/s³]; ``value.onnx``: state (n, 108) → value (n,).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import torch
from torch import nn

from crossroads.constants import STATE_DIM
from crossroads.rl.checkpoint import load_networks

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


def _export(module: nn.Module, path: Path, output: str) -> None:
    example = torch.zeros(2, STATE_DIM)
    # (choice) the TorchScript exporter: plain MLPs need nothing more, and it needs no onnxscript;
    # torch warns that it is deprecated in favour of the torch.export-based one
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.onnx.export(module.eval(), (example,), str(path), dynamo=False, opset_version=OPSET,
                          input_names=["state"], output_names=[output],
                          dynamic_axes={"state": {0: "batch"}, output: {0: "batch"}})


def export_onnx(model: Path, out_dir: Path) -> tuple[Path, Path]:
    """Write ``policy.onnx`` and ``value.onnx`` of a model file or checkpoint into ``out_dir``."""
    nets, _ = load_networks(model)
    out_dir.mkdir(parents=True, exist_ok=True)
    policy_path, value_path = out_dir / "policy.onnx", out_dir / "value.onnx"
    _export(_MeanAction(nets.policy), policy_path, "action")
    _export(nets.value, value_path, "value")
    return policy_path, value_path


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
