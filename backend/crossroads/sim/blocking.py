"""Runs the world lost, not the driver: the ego's way barred by a participant that never moved.

Every candidate path of the ego starts in its entrance lane, so a vehicle or cyclist standing
ahead of the ego across all of them (in that lane, or at the start of the junction where the paths
have not yet parted) bars every way through. When an episode times out behind one that has stood
since (almost) the start, no driver could have passed it: the run is *blocked by the world*
(``Outcome.blocked_by``), counted apart in reports, while the pass rate keeps the paper's
definition (passed / judged).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

from crossroads.constants import EGO_WIDTH_M
from crossroads.geometry import distances_to_polyline
from crossroads.planning import CandidatePath

HELD_FROM_S = 5.0  # [s] a participant standing since at most this far into the episode held it throughout


@dataclass(frozen=True)
class BlockedBy:
    """The participant that barred every candidate path of a timed-out episode."""

    participant: str  # SUMO id
    kind: str  # vehicle | cyclist
    stood_s: float  # [s] how long it had stood when the episode ended
    ahead_m: float  # [m] from the ego's centre to its centre, along the first candidate path

    def to_json(self) -> dict[str, object]:
        return asdict(self)


def bars_every_path(x: float, y: float, width: float, candidates: Sequence[CandidatePath]) -> bool:
    """Whether a body of ``width`` [m] centred at (x, y) overlaps every candidate path's swept band
    (the ego's width): the ego cannot drive past it on any of them."""
    reach = (width + EGO_WIDTH_M) / 2.0
    return all(float(distances_to_polyline([(x, y)], c.points)[0]) < reach for c in candidates)


def nearest_barrier(ego_xy: tuple[float, float], bodies: Sequence[tuple[int, float, float, float]],
                    candidates: Sequence[CandidatePath]) -> tuple[int, float] | None:
    """Of ``bodies`` (row, x, y, width), the nearest ahead of the ego along the first candidate path
    that bars every path: (row, distance ahead [m]), or None."""
    path = candidates[0]  # a barrier bars them all: along any one of them is as good
    ego_s = path.project(*ego_xy).s_m
    best: tuple[int, float] | None = None
    for row, x, y, width in bodies:
        if not bars_every_path(x, y, width, candidates):
            continue
        gap = path.project(x, y).s_m - ego_s
        if gap > 0.0 and (best is None or gap < best[1]):
            best = (row, gap)
    return best


def held_whole_episode(stood_s: float, episode_time_s: float) -> bool:
    """Whether a participant that has stood ``stood_s`` stood since at most :data:`HELD_FROM_S`
    into an episode now ``episode_time_s`` long."""
    return stood_s >= episode_time_s - HELD_FROM_S
