"""Python policies (``--policy py:package.module:Factory``): your own class drives the ego.

``Factory`` is called with no arguments and must return an object of the controller protocol
(:class:`crossroads.idc.controller.Controller`):

* ``name: str`` (optional; the reference's ``Factory`` otherwise), a label for traces and reports;
* ``reset(candidates)`` at the start of every episode, with the task's candidate paths
  (:class:`crossroads.planning.CandidatePath`: ``points`` (n, 2) [m], ``heading``, ``s``, the
  pass/stop speed profiles, ...);
* ``decide(observation) -> Decision`` every 0.1 s, with a
  :class:`crossroads.sim.observation.Observation` (the ego's state, the light, the distance to the stop
  line, the perceived participants with their noise, the candidates, the map); the
  :class:`~crossroads.idc.controller.Decision` holds the action [Δδ rad/s, Δa m/s³] (clipped to
  ±0.4 and ±4.5 by the ego model), the index of the candidate it follows and its speed mode.

The module is imported in every process that runs episodes (the CLI, each batch worker process, each
Ray actor), so it must be importable there: installed, or its directory on ``PYTHONPATH`` (a local
batch's worker processes also inherit the caller's ``sys.path``). Each decision is checked (type,
shape, finite action, valid path index and mode) so that a faulty plugin fails its episode with a
message naming the field, not somewhere deep in the world. ``examples/plugin_driver`` has a minimal one.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Sequence
from typing import Any

import numpy as np

from crossroads.idc.controller import Controller, Decision
from crossroads.planning import CandidatePath
from crossroads.policy.ref import PLUGIN_PREFIX, PolicyError
from crossroads.sim.observation import Observation

SPEED_MODES = ("pass", "stop")


class PluginController:
    """A plugin's controller with every decision checked (module docstring); ``inner`` is the
    plugin's own object."""

    def __init__(self, inner: Any, reference: str, name: str) -> None:
        self.inner = inner
        self.reference = reference
        own = getattr(inner, "name", None)
        self.name = own if isinstance(own, str) and own else name
        self._candidates = 0

    def reset(self, candidates: Sequence[CandidatePath]) -> None:
        self._candidates = len(candidates)
        self.inner.reset(candidates)

    def decide(self, observation: Observation) -> Decision:
        decision = self.inner.decide(observation)
        where = f"{self.reference}: decide() returned"
        if not isinstance(decision, Decision):
            raise PolicyError(f"{where} a {type(decision).__name__}; it must return a "
                              "crossroads.idc.controller.Decision")
        action = np.asarray(decision.action, dtype=np.float64)
        if action.shape != (2,) or not np.isfinite(action).all():
            raise PolicyError(f"{where} action {decision.action!r}; it must be 2 finite numbers "
                              "[Δδ rad/s, Δa m/s³]")
        index = decision.path_index
        if isinstance(index, bool) or not isinstance(index, int | np.integer) or not 0 <= index < self._candidates:
            raise PolicyError(f"{where} path_index {index!r}; it must be the index of a candidate "
                              f"path (0..{self._candidates - 1})")
        if decision.speed_mode not in SPEED_MODES:
            raise PolicyError(f"{where} speed_mode {decision.speed_mode!r}; it must be 'pass' or 'stop'")
        return decision


def load_plugin(target: str, *, name: str) -> Controller:
    """Import ``package.module``, call its ``Factory`` and check the result (:class:`PolicyError`)."""
    reference = PLUGIN_PREFIX + target
    module_name, _, attr = target.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise PolicyError(f"policy {reference!r}: cannot import {module_name!r} ({exc}); the module must "
                          "be importable by the Python that runs the episodes: install it, or put its "
                          "directory on PYTHONPATH") from exc
    factory = getattr(module, attr, None)
    if factory is None or not callable(factory):
        raise PolicyError(f"policy {reference!r}: module {module_name!r} has no callable {attr!r}")
    try:
        controller = factory()
    except Exception as exc:
        raise PolicyError(f"policy {reference!r}: {attr}() raised {type(exc).__name__}: {exc}") from exc
    missing = [m for m in ("reset", "decide") if not callable(getattr(controller, m, None))]
    if missing:
        raise PolicyError(f"policy {reference!r}: {attr}() returned a {type(controller).__name__} without "
                          f"{' and '.join(m + '()' for m in missing)}; a controller has reset(candidates) "
                          "and decide(observation) (crossroads.idc.controller.Controller)")
    return PluginController(controller, reference, name)
