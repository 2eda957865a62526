"""Policy ``sumo``: SUMO's own driver drives the ego, the baseline of what the world lets through.

The ego becomes an ordinary SUMO vehicle with the ego's footprint, on the route of the task's first
candidate path (its entrance lane to its exit edge), starting where and how the scenario says, at
the ego's speed limit, with a perfect Krauss driver (:class:`~crossroads.sim.sumo.SumoDriver`).
SUMO's car-following, junction and lane-change models — which know every participant exactly —
drive it; the world's judge rules on its true footprint like on any policy's. A run SUMO's driver
cannot pass is one few drivers could.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from crossroads.constants import V_LIMIT_MPS
from crossroads.idc.controller import Decision
from crossroads.planning import CandidatePath
from crossroads.sim.observation import Observation
from crossroads.sim.sumo import SumoDriver

SUMO_POLICY = "sumo"


@dataclass
class SumoDriverPolicy:
    """Stands for SUMO's driver where a controller is expected: :func:`run_episode` hands the ego
    to SUMO when it meets one, and :meth:`decide` only reports (no action of ours: NaN)."""

    driver: SumoDriver = field(default_factory=lambda: SumoDriver(max_speed_mps=V_LIMIT_MPS))
    name: str = SUMO_POLICY

    def reset(self, candidates: Sequence[CandidatePath]) -> None:
        """Nothing to prepare: SUMO plans its own way."""

    def decide(self, observation: Observation) -> Decision:
        return Decision(np.full(2, np.nan), 0, "pass")
