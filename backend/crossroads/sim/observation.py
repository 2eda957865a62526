"""What a controller sees after each step: the :class:`Observation` (the control contract).

The world (:class:`crossroads.sim.world.World`) fills it; controllers (``crossroads.idc``, plugins,
ONNX policies) read it. These are plain data types with no libsumo import, so a controller can be
imported, built and tested without SUMO.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from shapely.geometry import Polygon

from crossroads.geometry import FloatArray
from crossroads.planning import CandidatePath
from crossroads.sim.other import route_curvature
from crossroads.sim.signals import Light
from crossroads.sim.snapshot import Snapshot


@dataclass(frozen=True)
class LightView:
    """The signal the ego's approach sees."""

    light: Light  # "green" | "yellow" | "red"
    remaining_s: float  # [s] until it changes
    state: str  # the whole tlLogic state string (every link), for drawing


@dataclass(frozen=True)
class Perceived:
    """The participants the ego's sensors cover, with the noisy observation of each."""

    rows: np.ndarray  # indices into the snapshot
    kinds: np.ndarray  # "vehicle" | "cyclist" | "pedestrian"
    observations: FloatArray  # (n, 6): [p_x, p_y, v, φ, L, W], world frame, noisy


@dataclass(frozen=True)
class Observation:
    """What a controller may look at after a step (the true snapshot is for the trace and judge)."""

    time_s: float  # [s] since the ego entered
    ego: FloatArray  # (8,) [p_x, p_y, v_x, v_y, φ, ω, δ, a]
    light: LightView
    distance_to_stop_line_m: float  # [m] of the ego's front bumper; negative once past it
    front_vehicle_stopped_s: float  # [s] the vehicle ahead has been standing (0 if none/moving)
    participants: Snapshot  # true state of everyone but the ego
    abnormal_ids: frozenset[str]
    perceived: Perceived
    candidates: tuple[CandidatePath, ...]
    # lane centre lines by SUMO lane id (the junction's internal lanes included): static map
    # knowledge, as the candidates are, from which a controller can tell a participant's turning
    # radius (:func:`participant_curvatures`)
    lane_shapes: Mapping[str, FloatArray] = field(default_factory=dict)
    # the junction's pedestrian crossings (their areas): static map knowledge too, from which the
    # safety shield tells where the ego's path runs over one (crossroads.idc.crosswalks)
    crossings: tuple[Polygon, ...] = ()

    @property
    def past_stop_line(self) -> bool:
        return self.distance_to_stop_line_m < 0.0


def participant_curvatures(lane_shapes: Mapping[str, FloatArray], snap: Snapshot, rows: np.ndarray) -> FloatArray:
    """Signed curvature 1/R [1/m] of the participants at ``rows`` of ``snap``, from their lane and
    position (0 on lanes ``lane_shapes`` does not describe, and for pedestrians): the R of f_other."""
    kappa = np.zeros(len(rows))
    for k, row in enumerate(rows):
        shape = lane_shapes.get(str(snap.lane_id[row]))
        if shape is not None and snap.kind[row] != "pedestrian":
            kappa[k] = route_curvature(shape, float(snap.x[row]), float(snap.y[row]))
    return kappa
