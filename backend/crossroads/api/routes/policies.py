"""Policies: the built-in rule-based controller and the checkpoints shipped under models/."""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter

from crossroads.api.deps import OptionsDep, unprocessable
from crossroads.api.schemas import PolicyPublic
from crossroads.evaluation.policies import BUILTIN_POLICIES, SHIELD_SUFFIX, read_model_card

router = APIRouter(prefix="/policies", tags=["policies"])

REPO_MODELS_DIR = Path(__file__).resolve().parents[4] / "models"  # <repo>/backend/crossroads/api/routes


def models_dir(configured: Path | None) -> Path:
    return configured if configured is not None else REPO_MODELS_DIR


def available_policies(directory: Path) -> list[PolicyPublic]:
    """``rule`` first, then every ``<name>.pt`` of ``directory`` (sorted) with its card, each
    followed by ``<name>+shield``: the same networks with the safety shield (``idc.shield``)."""
    found = [PolicyPublic(name=name, kind="builtin") for name in BUILTIN_POLICIES]
    if directory.is_dir():
        for path in sorted(directory.glob("*.pt")):
            if not path.is_file() or path.stem in BUILTIN_POLICIES:
                continue
            card, size = read_model_card(path), path.stat().st_size
            for shield in (False, True):
                found.append(PolicyPublic(name=path.stem + (SHIELD_SUFFIX if shield else ""), kind="checkpoint",
                                          file=path.name, shield=shield, size_bytes=size, card=card))
    return found


def policy_ref(name: str, directory: Path, *, field: str = "policy") -> str:
    """What the batch runner takes for a policy name: ``rule`` or the checkpoint's path (with
    ``+shield`` for a shielded one).

    Only names listed by GET /policies are accepted: a client never names a server path."""
    for policy in available_policies(directory):
        if policy.name == name:
            if policy.kind == "builtin":
                return name
            return str(directory / (policy.file or "")) + (SHIELD_SUFFIX if policy.shield else "")
    known = ", ".join(p.name for p in available_policies(directory))
    raise unprocessable([(field, f"unknown policy {name!r}; known: {known}")])


@router.get("")
def list_policies(options: OptionsDep) -> list[PolicyPublic]:
    """The policies a batch can run: ``rule`` and the checkpoints (models/*.pt) with their cards,
    each also with the safety shield (``<name>+shield``)."""
    return available_policies(models_dir(options.models_dir))
