"""Crossroads as a Gymnasium environment: ``Crossroads-v0`` (:class:`crossroads.gym.env.CrossroadsEnv`).

Importing this package registers the id; ``gym.make("crossroads.gym:Crossroads-v0", ...)`` imports
it for you. Arguments of ``gym.make``: ``scenario`` (a scenario file, or a catalogue intersection
with ``task``), ``observation`` ("box" | "dict"), ``path`` ("nearest" | a candidate index),
``preview`` (the 12 path-preview values after the 108), ``reward`` (a :class:`RewardConfig`).
The guide: docs/guide/own-driver.md.
"""

from __future__ import annotations

import gymnasium

from crossroads.gym.env import CrossroadsEnv, scenario_spec
from crossroads.gym.reward import RewardConfig

ENV_ID = "Crossroads-v0"

__all__ = ["ENV_ID", "CrossroadsEnv", "RewardConfig", "scenario_spec"]

if ENV_ID not in gymnasium.registry:
    # no max_episode_steps: the scenario's timeout ends an episode (truncated), not a wrapper
    gymnasium.register(id=ENV_ID, entry_point="crossroads.gym.env:CrossroadsEnv")
