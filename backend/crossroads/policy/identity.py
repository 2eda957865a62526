"""Who a policy is, for the results store: a policy reference's identity and its model card.

A built-in policy is its name (``builtin:rule``); a checkpoint or an ONNX file is the sha256 of its
bytes (with ``+shield``, a policy of its own); a Python plugin is the sha256 of its reference and
its module's source file. So a policy edited in place is a new policy, and the same file under
another name is the same one.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from crossroads.policy.ref import PLUGIN_PREFIX, SHIELD_SUFFIX, PolicyError, parse_policy

HASH_CHUNK = 1 << 20
CARD_SUFFIXES = (".card.json", ".json")  # a checkpoint's model card: models/apg.pt → apg.card.json


def file_sha256(path: str | Path) -> str:
    digest = hashlib.sha256()
    with Path(path).open("rb") as f:
        while chunk := f.read(HASH_CHUNK):
            digest.update(chunk)
    return digest.hexdigest()


@dataclass(frozen=True)
class PolicyIdentity:
    """Who a policy reference is: ``builtin:rule``, the sha256 of a checkpoint's or an ONNX file's
    bytes, or for a Python plugin the sha256 of its reference and its module's source file."""

    name: str
    ref: str  # the canonical reference (crossroads.policy.ref.PolicyRef as text)
    kind: str  # builtin | checkpoint | onnx | plugin
    file_hash: str
    card: dict[str, Any] | None


def policy_identity(ref: str) -> PolicyIdentity:
    """The identity of ``ref`` (parsed by :func:`~crossroads.policy.ref.parse_policy`). A
    file's card is read from a ``<stem>.card.json`` or ``<stem>.json`` next to it when there is one.
    A checkpoint or ONNX file with the safety shield (``+shield``) is a policy of its own: name and
    hash carry the suffix. A plugin is named by its reference and hashed with its module's source
    file (an edited plugin is a new policy; the modules it imports are not hashed)."""
    parsed = parse_policy(ref)
    text = str(parsed)
    if parsed.kind in ("rule", "sumo"):
        return PolicyIdentity(text, text, "builtin", f"builtin:{text}", None)
    if parsed.kind == "plugin":
        digest = hashlib.sha256(f"{parsed.target}\n{file_sha256(plugin_source(parsed.target))}".encode())
        return PolicyIdentity(parsed.name, text, "plugin", f"py:sha256:{digest.hexdigest()}", None)
    path = Path(parsed.target)
    if not path.is_file():
        what = "checkpoint" if parsed.kind == "checkpoint" else "ONNX file"
        raise PolicyError(f"policy {what} {parsed.target!r} does not exist")
    card = read_model_card(path)
    suffix = SHIELD_SUFFIX if parsed.shield else ""
    return PolicyIdentity(parsed.name, text, parsed.kind, f"sha256:{file_sha256(path)}{suffix}", card)


def plugin_source(target: str) -> Path:
    """The source file of a plugin's module (what its identity in the results store hashes)."""
    module_name = target.partition(":")[0]
    try:
        spec = importlib.util.find_spec(module_name)
    except (ImportError, ValueError) as exc:
        spec, reason = None, f" ({exc})"
    else:
        reason = ""
    if spec is None or not spec.origin or not Path(spec.origin).is_file():
        raise PolicyError(f"policy {PLUGIN_PREFIX + target!r}: no source file for module {module_name!r}{reason}; "
                          "it must be importable (installed, or its directory on PYTHONPATH)")
    return Path(spec.origin)


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
