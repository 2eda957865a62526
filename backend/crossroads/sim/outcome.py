"""How an episode ended (:class:`Outcome`), as the world's judge decides it on the true footprints.

Plain data with no libsumo import: evaluation, reports and tools read it without SUMO.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from crossroads.sim.blocking import BlockedBy

OutcomeKind = Literal["passed", "collision", "red_light", "off_road", "timeout"]
OUTCOMES: tuple[OutcomeKind, ...] = ("passed", "collision", "red_light", "off_road", "timeout")


@dataclass(frozen=True)
class Outcome:
    """How an episode ended."""

    kind: OutcomeKind
    time_s: float  # [s] since the ego entered
    detail: str = ""  # e.g. which participant was hit
    other_kind: str | None = None  # collision: "vehicle" | "cyclist" | "pedestrian"
    # timeout: the participant that barred every candidate path the whole episode, if one did
    # (the world's failure, not the driver's: sim/blocking.py)
    blocked_by: BlockedBy | None = None
