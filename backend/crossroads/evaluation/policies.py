"""A controller for a policy reference (:class:`~crossroads.policy.ref.PolicyRef`): :func:`load_controller`.

The grammar of the references is :mod:`crossroads.policy.ref`; this module turns a parsed one into
what drives the ego: the rule-based baseline, SUMO's driver (a stand-in the episode runner hands the
ego to SUMO on meeting), a trained checkpoint's networks in the IDC decision, an ONNX network, or a
Python plugin, with the safety shield where the reference asks for it.
"""

from __future__ import annotations

import pickle
from pathlib import Path

from crossroads.idc.controller import Controller
from crossroads.policy.ref import PolicyError, PolicyRef


def load_controller(ref: PolicyRef) -> Controller:
    """A fresh controller for ``ref``. For ``sumo`` it is the stand-in
    :class:`~crossroads.evaluation.sumo_driver.SumoDriverPolicy`, on meeting which
    :func:`~crossroads.evaluation.episode.run_episode` hands the ego to SUMO's own driver."""
    if ref.kind == "rule":
        from crossroads.idc.rule_based import RuleBasedController

        return RuleBasedController()
    if ref.kind == "sumo":
        from crossroads.evaluation.sumo_driver import SumoDriverPolicy

        return SumoDriverPolicy()
    if ref.kind == "plugin":
        from crossroads.evaluation.plugin_policy import load_plugin

        return load_plugin(ref.target, name=ref.name)
    path = Path(ref.target)
    kind = "checkpoint" if ref.kind == "checkpoint" else "ONNX policy"
    if not path.is_file():
        raise PolicyError(f"policy {kind} {ref.target!r} does not exist")
    if ref.kind == "onnx":
        from crossroads.evaluation.onnx_policy import OnnxError, load_onnx_controller

        try:
            return load_onnx_controller(path, name=ref.name, shield=ref.shield)
        except OnnxError as exc:
            raise PolicyError(f"policy {str(ref)!r}: {exc}") from None
    try:
        from crossroads.idc.decision import IdcController  # needs the trained networks
        from crossroads.rl.checkpoint import load_networks
    except ImportError as exc:
        raise PolicyError(f"policy {str(ref)!r}: this build cannot load trained checkpoints ({exc})") from exc
    try:
        networks, _ = load_networks(path)
    except (ValueError, OSError, RuntimeError, pickle.UnpicklingError) as exc:
        raise PolicyError(f"policy {str(ref)!r}: cannot load the checkpoint ({exc})") from exc
    return IdcController(networks.policy, networks.value, name=ref.name, shield=ref.shield)
