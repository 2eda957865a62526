"""Policies: the built-in rule-based controller and the checkpoints shipped under models/."""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter

from crossroads.api.deps import OptionsDep, unprocessable
from crossroads.api.schemas import PolicyPublic
from crossroads.evaluation.policies import BUILTIN_POLICIES
from crossroads.evaluation.policies import read_model_card

router = APIRouter(prefix="/policies", tags=["policies"])

REPO_MODELS_DIR = Path(__file__).resolve().parents[4] / "models"  # <repo>/backend/crossroads/api/routes


def models_dir(configured: Path | None) -> Path:
    return configured if configured is not None else REPO_MODELS_DIR


def available_policies(directory: Path) -> list[PolicyPublic]:
    """``rule`` first, then every ``<name>.pt`` of ``directory`` (sorted) with its card."""
    found = [PolicyPublic(name=name, kind="builtin") for name in BUILTIN_POLICIES]
    if directory.is_dir():
        for path in sorted(directory.glob("*.pt")):
            if not path.is_file() or path.stem in BUILTIN_POLICIES:
                continue
            card = read_model_card(path)
            found.append(PolicyPublic(name=path.stem, kind="checkpoint", file=path.name,
                                      size_bytes=path.stat().st_size, card=card))
    return found


def policy_ref(name: str, directory: Path, *, field: str = "policy") -> str:
    """What the batch runner takes for a policy name: ``rule`` or the checkpoint's path.

    Only names listed by GET /policies are accepted: a client never names a server path."""
    for policy in available_policies(directory):
        if policy.name == name:
            return name if policy.kind == "builtin" else str(directory / (policy.file or ""))
    known = ", ".join(p.name for p in available_policies(directory))
    raise unprocessable([(field, f"unknown policy {name!r}; known: {known}")])


@router.get("")
def list_policies(options: OptionsDep) -> list[PolicyPublic]:
    """The policies a batch can run: ``rule`` and the checkpoints (models/*.pt) with their cards."""
    return available_policies(models_dir(options.models_dir))
