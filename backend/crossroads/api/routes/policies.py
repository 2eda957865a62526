"""Policies: the built-in rule-based controller, the checkpoints shipped under models/ and the uploaded
ONNX policies (``routes.policy_uploads``)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, Depends, Response

from crossroads.api.deps import OptionsDep, SettingsDep, unprocessable
from crossroads.api.params import Page, paging
from crossroads.api.routes.policy_uploads import uploaded_policies, uploaded_ref
from crossroads.api.schemas import PolicyPublic
from crossroads.policy.ref import BUILTIN_POLICIES, SHIELD_SUFFIX, SUMO_DRIVER, PolicyRef
from crossroads.policy.identity import read_model_card

router = APIRouter(prefix="/policies", tags=["policies"])

REPO_MODELS_DIR = Path(__file__).resolve().parents[4] / "models"  # <repo>/backend/crossroads/api/routes


def models_dir(configured: Path | None) -> Path:
    return configured if configured is not None else REPO_MODELS_DIR


def available_policies(directory: Path, data_dir: Path | None = None) -> list[PolicyPublic]:
    """``rule`` and ``sumo`` (SUMO's own driver) first, then every ``<name>.pt`` of ``directory`` (sorted) with its card, each
    followed by ``<name>+shield``: the same networks with the safety shield (``idc.shield``); then,
    with ``data_dir``, the uploaded ONNX policies alike (``routes.policy_uploads``)."""
    found = [PolicyPublic(name=name, kind="builtin") for name in (*BUILTIN_POLICIES, SUMO_DRIVER)]
    if directory.is_dir():
        for path in sorted(directory.glob("*.pt")):
            if not path.is_file() or path.stem in BUILTIN_POLICIES:
                continue
            card, size = read_model_card(path), path.stat().st_size
            for shield in (False, True):
                found.append(PolicyPublic(name=path.stem + (SHIELD_SUFFIX if shield else ""), kind="checkpoint",
                                          file=path.name, shield=shield, size_bytes=size, card=card))
    if data_dir is not None:
        found += uploaded_policies(data_dir)
    return found


def policy_ref(name: str, directory: Path, *, field: str = "policy", data_dir: Path | None = None) -> str:
    """What the batch runner takes for a policy name: ``rule``, the checkpoint's path or an uploaded
    ONNX policy's ``onnx:PATH`` (with ``+shield`` for a shielded one).

    Only names listed by GET /policies are accepted: a client never names a server path."""
    listed = available_policies(directory, data_dir)
    for policy in listed:
        if policy.name == name:
            if policy.kind == "builtin":
                return name
            if policy.kind == "onnx" and data_dir is not None:
                return uploaded_ref(policy, data_dir)
            return str(PolicyRef("checkpoint", str(directory / (policy.file or "")), policy.shield))
    known = ", ".join(p.name for p in listed)
    raise unprocessable([(field, f"unknown policy {name!r}; known: {known}")])


@router.get("")
def list_policies(options: OptionsDep, settings: SettingsDep, response: Response,
                  page: Annotated[Page, Depends(paging(1000, 1000))]) -> list[PolicyPublic]:
    """The policies a batch can run: ``rule``, the checkpoints (models/*.pt) with their cards and
    the uploaded ONNX policies with their sha256 and card, each also with the safety shield
    (``<name>+shield``)."""
    return page.slice(available_policies(models_dir(options.models_dir), settings.data_dir), response)
