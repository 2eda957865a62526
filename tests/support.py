"""Paths and helpers shared by the tests (import as ``from support import ...``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("CROSSROADS_SHARED_DIR", REPO_ROOT.parent / "shared"))
REALNETS = SHARED / "realnets"
COLOGNE1_NET = REALNETS / "resco_cologne1" / "cologne1.net.xml"
SUMO_RL_NET = REALNETS / "sumo-rl_2way-single-intersection" / "single-intersection.net.xml"


def sumo_example(relative: str) -> Path:
    """A network shipped with SUMO itself (inside the eclipse-sumo wheel)."""
    import sumo

    return Path(sumo.SUMO_HOME) / relative


SUMO_CROSS_NET = "tools/game/cross/cross.net.xml"


# One episode in a fresh Python process (as ``crossroads run``: SUMO's result can depend on what
# the process ran before), after "module:NAME=python expression" patches of module attributes.
# argv: scenario, policy, seed, WorldConfig changes (JSON), SumoDriver changes (JSON), patches...;
# prints [outcome, detail, the events' names] as JSON.
_PATCHED_EPISODE = """
import dataclasses, importlib, json, math, sys
import numpy as np
from pathlib import Path
for patch in sys.argv[6:]:
    target, expression = patch.split("=", 1)
    module_name, name = target.split(":")
    module = importlib.import_module(module_name)
    setattr(module, name, eval(expression, {**vars(module), "math": math, "np": np}))
from crossroads.evaluation.episode import run_episode
from crossroads.evaluation.policies import load_controller
from crossroads.policy.ref import parse_policy
from crossroads.scenario.spec import load_scenario, to_world_config
from crossroads.sim.world import World
path, policy, seed = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3])
world_changes, driver_changes = json.loads(sys.argv[4]), json.loads(sys.argv[5])
controller = load_controller(parse_policy(policy))
if driver_changes:
    controller = dataclasses.replace(controller, driver=dataclasses.replace(controller.driver, **driver_changes))
config = dataclasses.replace(to_world_config(load_scenario(path), path.parent), **world_changes)
with World(config) as world:
    result = run_episode(world, controller, seed=seed)
print(json.dumps([result.outcome, result.detail, [e["event"] for e in result.events]]))
"""


def patched_episode(scenario: str, policy: str, seed: int, *patches: str, world: dict | None = None,
                    driver: dict | None = None) -> list:
    """[outcome, detail, event names] of one episode of ``scenarios/nominal/{scenario}.yaml`` with
    ``policy`` (``sumo``, ``rule``, ...) and ``seed`` in a fresh process, after ``patches``
    ("module:NAME=python expression", evaluated in that module's namespace with ``math`` and ``np``
    at hand), with the scenario's world config changed by ``world`` (WorldConfig fields) and, for
    ``sumo``, SUMO's driver by ``driver`` (SumoDriver fields)."""
    done = subprocess.run([sys.executable, "-c", _PATCHED_EPISODE,
                           str(REPO_ROOT / f"scenarios/nominal/{scenario}.yaml"), policy, str(seed),
                           json.dumps(world or {}), json.dumps(driver or {}), *patches],
                          capture_output=True, text=True, timeout=300, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])
