"""What the world holds at one instant: every participant but the ego, as parallel arrays.

The true state the world reads from SUMO each step (:meth:`crossroads.sim.sumo.SumoSession.snapshot`
fills it): the judge decides on it, the sensors perceive from it. A plain data type that imports no
libsumo, so controllers and tools can take it without SUMO.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from crossroads.constants import PARTICIPANT_KINDS

Kind = Literal["vehicle", "cyclist", "pedestrian"]
KINDS: tuple[Kind, ...] = PARTICIPANT_KINDS
KIND_CODE: dict[str, int] = {kind: code for code, kind in enumerate(KINDS)}


@dataclass(frozen=True)
class Snapshot:
    """Every participant SUMO has at one instant (the ego excluded), as parallel arrays.

    ``x``, ``y`` [m] are footprint centres; ``heading`` [rad] CCW from +x; ``speed`` [m/s];
    ``length``/``width`` [m]. ``lane_id``/``edge_id`` are SUMO's ("" when off the network).
    ``route`` holds each participant's edges (vehicles: its route; pedestrians: the edges of the
    current walk).
    """

    time_s: float
    ids: NDArray[np.str_]
    kind: NDArray[np.str_]
    kind_code: NDArray[np.int8]  # index into KINDS (cheaper to compare than the strings)
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    heading: NDArray[np.float64]
    speed: NDArray[np.float64]
    length: NDArray[np.float64]
    width: NDArray[np.float64]
    route: tuple[tuple[str, ...], ...]
    read_lanes: Callable[[], tuple[str, ...]]
    """Reads every participant's lane from SUMO, in the same step only (see ``lane_id``)."""

    def __len__(self) -> int:
        return len(self.ids)

    @functools.cached_property
    def observation_rows(self) -> NDArray[np.float64]:
        """(n, 6) rows ``[x, y, speed, heading, length, width]``, the layout of an observation."""
        rows = np.empty((len(self.ids), 6))  # filled column by column: np.column_stack's work, less overhead
        for k, column in enumerate((self.x, self.y, self.speed, self.heading, self.length, self.width)):
            rows[:, k] = column
        return rows

    @functools.cached_property
    def lane_id(self) -> NDArray[np.str_]:
        """SUMO lane of each participant. Read when first asked (most steps never ask: the control
        loop does not need it), so it must be asked before the session steps again; later it
        raises :class:`~crossroads.sim.sumo.SumoError`."""
        return np.array(self.read_lanes(), dtype=np.str_)

    @functools.cached_property
    def edge_id(self) -> NDArray[np.str_]:
        """SUMO edge of each participant ("" when off the network), from its lane id."""
        return np.array([lane.rsplit("_", 1)[0] if lane else "" for lane in self.lane_id],
                        dtype=np.str_)

    def of_kind(self, kind: Kind) -> NDArray[np.bool_]:
        """Boolean mask of the participants of one kind."""
        return self.kind == kind

    def index(self, participant_id: str) -> int:
        """Row of a participant; KeyError if it is not in the snapshot."""
        rows = np.flatnonzero(self.ids == participant_id)
        if len(rows) == 0:
            raise KeyError(participant_id)
        return int(rows[0])
