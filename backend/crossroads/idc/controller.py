"""The controller interface: what drives the ego in an episode (the rule baseline or a trained IDC).

A controller sees an :class:`~crossroads.sim.observation.Observation` each step and answers with a
:class:`Decision`: the action [Δδ, Δa] plus what it decided on the way (the chosen candidate path,
the speed mode, the path values), which the trace records for playback.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

from crossroads.geometry import FloatArray
from crossroads.planning import CandidatePath
from crossroads.sim.observation import Observation

SpeedMode = Literal["pass", "stop"]


@dataclass(frozen=True)
class Decision:
    action: FloatArray  # (2,) [Δδ rad/s, Δa m/s³]
    path_index: int  # index of the chosen candidate path
    speed_mode: SpeedMode
    path_values: FloatArray | None = None  # value of every candidate (IDC: v_w; lower is better)
    shield_braking: bool | None = None  # a safety shield replaced the action by braking (None: no shield)


class Controller(Protocol):
    """Anything that can drive the ego."""

    name: str

    def reset(self, candidates: Sequence[CandidatePath]) -> None:
        """A new episode starts on these candidate paths."""

    def decide(self, observation: Observation) -> Decision:
        """The decision for this step (called every 0.1 s)."""


def zero_decision() -> Decision:
    return Decision(np.zeros(2), 0, "pass")
