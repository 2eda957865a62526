"""Policy references: what ``--policy`` accepts on the command line and ``policy`` in the API.

One grammar, parsed in one place (:func:`parse_policy`) into a typed :class:`PolicyRef`:

=============================  ==========  =====================================================
text                           kind        what drives the ego
=============================  ==========  =====================================================
``rule``                       rule        the rule-based baseline (:mod:`crossroads.idc.rule_based`)
``sumo``                       sumo        SUMO's own driver model: the episode runner hands the
                                           ego to SUMO (:mod:`crossroads.evaluation.sumo_driver`)
``models/apg.pt``              checkpoint  the IDC decision driven by a trained run's networks
``onnx:PATH.onnx`` (or a bare  onnx        a network mapping the IDC state to the action (and
``PATH.onnx``)                             optionally a value per candidate path), run by
                                           onnxruntime (:mod:`crossroads.evaluation.onnx_policy`)
``py:package.module:Factory``  plugin      a Python class implementing the controller protocol
                                           (:mod:`crossroads.evaluation.plugin_policy`)
=============================  ==========  =====================================================

``+shield`` appended to a checkpoint or an ONNX reference (``models/apg.pt+shield``) adds the safety
shield (:mod:`crossroads.idc.shield`) between the networks and the ego; it checks a network's plan, so
the others refuse it. ``str(ref)`` is the canonical text, the form the results store keeps.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

PolicyKind = Literal["rule", "sumo", "checkpoint", "onnx", "plugin"]
POLICY_KINDS: tuple[PolicyKind, ...] = ("rule", "sumo", "checkpoint", "onnx", "plugin")
BUILTIN_POLICIES = ("rule",)  # built-in controllers (``sumo`` is a driver of the world, not a controller)
SUMO_DRIVER = "sumo"
SHIELD_SUFFIX = "+shield"  # models/apg.pt+shield: the same networks, their actions checked (idc.shield)
ONNX_PREFIX = "onnx:"
PLUGIN_PREFIX = "py:"
CHECKPOINT_SUFFIX = ".pt"
ONNX_SUFFIX = ".onnx"
SHIELDABLE: tuple[PolicyKind, ...] = ("checkpoint", "onnx")
_DOTTED = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
FORMS = ("rule", "sumo", "PATH.pt", "onnx:PATH.onnx", "py:package.module:Factory")


class PolicyError(ValueError):
    """The policy reference names nothing Crossroads can drive with."""


@dataclass(frozen=True)
class PolicyRef:
    """A parsed policy reference (see the module docstring for the grammar).

    ``target``: the file of a checkpoint or ONNX policy, ``package.module:Factory`` of a plugin,
    empty for ``rule`` and ``sumo``; ``shield``: the safety shield checks its actions."""

    kind: PolicyKind
    target: str = ""
    shield: bool = False

    def __post_init__(self) -> None:
        if self.kind not in POLICY_KINDS:
            raise PolicyError(f"policy kind {self.kind!r} is not one of {', '.join(POLICY_KINDS)}")
        if self.shield and self.kind not in SHIELDABLE:
            raise PolicyError(
                f"policy {self._text(False) + SHIELD_SUFFIX!r}: the safety shield checks a trained "
                f"policy's plan, and {self._text(False)!r} has none; use a checkpoint (.pt{SHIELD_SUFFIX}) "
                f"or an ONNX policy (onnx:PATH.onnx{SHIELD_SUFFIX})")
        if (self.kind in ("rule", "sumo")) != (self.target == ""):
            raise PolicyError(f"policy kind {self.kind!r}: target {self.target!r} "
                              + ("must be empty" if self.kind in ("rule", "sumo") else "is missing"))

    def _text(self, shield: bool) -> str:
        suffix = SHIELD_SUFFIX if shield else ""
        if self.kind in ("rule", "sumo"):
            return self.kind + suffix
        if self.kind == "onnx":
            return ONNX_PREFIX + self.target + suffix
        if self.kind == "plugin":
            return PLUGIN_PREFIX + self.target
        return self.target + suffix

    def __str__(self) -> str:
        return self._text(self.shield)

    @property
    def path(self) -> Path | None:
        """The file of a checkpoint or ONNX policy (None for the others)."""
        return Path(self.target) if self.kind in ("checkpoint", "onnx") else None

    @property
    def name(self) -> str:
        """A short display name: ``rule``, ``apg+shield``, ``my_driver`` (an ONNX file's stem),
        ``Factory`` (a plugin's class)."""
        if self.kind in ("rule", "sumo"):
            return self.kind
        if self.kind == "plugin":
            return self.target.rsplit(":", 1)[1]
        return Path(self.target).stem + (SHIELD_SUFFIX if self.shield else "")


def parse_policy(text: str) -> PolicyRef:
    """The :class:`PolicyRef` of a policy reference as a user writes it (module docstring).

    Only the form is checked here (and, for a bare path, whether it names a file): whether a file
    exists and loads is :func:`load_controller`'s to say."""
    if not isinstance(text, str) or not text.strip():
        raise PolicyError(f"empty policy reference; use one of {', '.join(FORMS)}")
    text = text.strip()
    body, shield = (text[: -len(SHIELD_SUFFIX)], True) if text.endswith(SHIELD_SUFFIX) else (text, False)
    if body in ("rule", SUMO_DRIVER):
        return PolicyRef(body, "", shield)  # type: ignore[arg-type]
    if body.startswith(PLUGIN_PREFIX):
        target = body[len(PLUGIN_PREFIX):]
        module, sep, attr = target.partition(":")
        if not sep or not _DOTTED.match(module) or not _NAME.match(attr):
            raise PolicyError(f"policy {text!r}: a Python policy is py:package.module:Factory "
                              "(a dotted module path, a colon, the name of a class or function in it)")
        return PolicyRef("plugin", target, shield)
    if body.startswith(ONNX_PREFIX):
        target = body[len(ONNX_PREFIX):]
        if not target.endswith(ONNX_SUFFIX):
            raise PolicyError(f"policy {text!r}: an ONNX policy is onnx:PATH{ONNX_SUFFIX}, "
                              f"and {target!r} does not end in {ONNX_SUFFIX}")
        return PolicyRef("onnx", target, shield)
    if body.endswith(ONNX_SUFFIX):
        return PolicyRef("onnx", body, shield)
    if body.endswith(CHECKPOINT_SUFFIX) or Path(body).exists():
        return PolicyRef("checkpoint", body, shield)
    raise PolicyError(f"unknown policy {text!r}: use one of {', '.join(FORMS)} "
                      f"(a checkpoint or ONNX file, with {SHIELD_SUFFIX} for the safety shield)")
