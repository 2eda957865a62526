"""Policies by name: what ``--policy`` accepts on the command line and in the API.

``rule`` is the rule-based baseline (:mod:`crossroads.idc.rule_based`); a path to a trained
checkpoint (``models/apg.pt``) is the IDC decision module driven by its networks, and the same
path with ``+shield`` appended (``models/apg.pt+shield``) adds the safety shield (``idc.shield``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from crossroads.idc.controller import Controller
from crossroads.idc.rule_based import RuleBasedController

BUILTIN_POLICIES = ("rule",)
SHIELD_SUFFIX = "+shield"  # models/apg.pt+shield: the same networks, their actions checked (idc.shield)
CARD_SUFFIXES = (".card.json", ".json")  # a checkpoint's model card: models/apg.pt → apg.card.json


class PolicyError(ValueError):
    """The policy reference names nothing Crossroads can drive with."""


def split_shield(ref: str) -> tuple[str, bool]:
    """(the policy reference without the suffix, whether it asks for the safety shield)."""
    return (ref[: -len(SHIELD_SUFFIX)], True) if ref.endswith(SHIELD_SUFFIX) else (ref, False)


def load_controller(ref: str) -> Controller:
    """A fresh controller for ``ref``: a built-in name or a checkpoint file, the latter with
    ``+shield`` appended for the IDC decision with the safety shield (``idc.shield``)."""
    ref, shield = split_shield(ref)
    if ref in BUILTIN_POLICIES:
        if shield:
            raise PolicyError(f"policy {ref + SHIELD_SUFFIX!r}: the safety shield checks a trained "
                              f"policy's plan, and {ref!r} has none; use a checkpoint (.pt{SHIELD_SUFFIX})")
        return RuleBasedController()
    path = Path(ref)
    if path.suffix == ".pt" or path.exists():
        if not path.is_file():
            raise PolicyError(f"policy checkpoint {ref!r} does not exist")
        try:
            from crossroads.idc.decision import IdcController  # needs the trained networks
        except ImportError as exc:
            raise PolicyError(
                f"policy {ref!r}: this build cannot load trained checkpoints yet ({exc})") from exc
        return IdcController.from_checkpoint(path, shield=shield)
    raise PolicyError(f"unknown policy {ref!r}: use one of {', '.join(BUILTIN_POLICIES)} "
                      "or the path of a trained checkpoint (.pt)")


def read_model_card(checkpoint: Path) -> dict[str, Any] | None:
    """The model card beside a checkpoint (``<stem>.card.json`` or ``<stem>.json``), if readable."""
    for suffix in CARD_SUFFIXES:
        candidate = checkpoint.with_name(checkpoint.stem + suffix)
        if candidate.is_file():
            try:
                card = json.loads(candidate.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                return None
            return card if isinstance(card, dict) else None
    return None

