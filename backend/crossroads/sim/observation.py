"""What a controller sees after each step: the :class:`Observation` (the control contract).

The world (:class:`crossroads.sim.world.World`) fills it; controllers (``crossroads.idc``, plugins,
ONNX policies) read it. It holds what the ego's sensors and map give (the ego's own state, the
light, the participants the sensors cover with their noise and the lane the map matches each to,
the candidate paths and the static map) and nothing of the world's true state: that is the
:class:`GroundTruth` beside it (``World.truth``), which the judge, the trace and the viewer read.
These are plain data types with no libsumo import, so a controller can be imported, built and
tested without SUMO.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import Polygon

from crossroads.geometry import FloatArray
from crossroads.planning import CandidatePath
from crossroads.sim.other import RouteShape, route_curvature, route_shape
from crossroads.sim.signals import Light
from crossroads.sim.snapshot import Snapshot


@dataclass(frozen=True)
class LightView:
    """The signal the ego's approach sees."""

    light: Light  # "green" | "yellow" | "red"
    remaining_s: float  # [s] until it changes
    state: str  # the whole tlLogic state string (every link), for drawing


def unmatched_lanes(indices: NDArray[np.intp]) -> NDArray[np.str_]:
    """No map matching: every participant on no known lane ("")."""
    return np.full(len(indices), "", dtype=np.str_)


@dataclass(frozen=True)
class Perceived:
    """The participants the ego's sensors cover, with the noisy observation of each."""

    rows: np.ndarray  # the sensors' track of each: its row in the world's GroundTruth snapshot
    kinds: np.ndarray  # "vehicle" | "cyclist" | "pedestrian"
    observations: FloatArray  # (n, 6): [p_x, p_y, v, φ, L, W], world frame, noisy
    lanes: Callable[[NDArray[np.intp]], NDArray[np.str_]] = unmatched_lanes
    """The SUMO lane the map matching puts each of the given perceived participants on (indices
    into ``observations``; "" where none). Asked for a few participants only, in the same step:
    reading a lane costs a call into SUMO."""
    kind_codes: NDArray[np.int8] | None = None  # (n,) each kind's index in PARTICIPANT_KINDS (None: not given)

    def slot_kinds(self) -> np.ndarray:
        """The kinds as :func:`~crossroads.idc.state.select_others` and its kin read them fastest:
        the codes where the world gave them, else the names (the same slots either way)."""
        return self.kinds if self.kind_codes is None else self.kind_codes


@dataclass(frozen=True)
class GroundTruth:
    """The world's true state after a step, which no controller gets: for the judge, the trace,
    the near-miss figures and the viewer."""

    participants: Snapshot  # true state of everyone but the ego
    abnormal_ids: frozenset[str]  # the over-speeding and rounding vehicles alive


@dataclass(frozen=True)
class Observation:
    """What a controller may look at after a step: the ego, the light, what the sensors cover and
    the map (module docstring)."""

    time_s: float  # [s] since the ego entered
    ego: FloatArray  # (8,) [p_x, p_y, v_x, v_y, φ, ω, δ, a]
    light: LightView
    distance_to_stop_line_m: float  # [m] of the ego's front bumper; negative once past it
    front_vehicle_stopped_s: float  # [s] the vehicle ahead has been standing (0 if none/moving)
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


class LaneShapes(dict[str, FloatArray]):
    """Lane centre lines by SUMO lane id (a plain mapping to (N, 2) arrays, as
    :attr:`Observation.lane_shapes` is typed), which also keeps each lane's :class:`RouteShape`
    once asked for it: the static map's geometry, read by :func:`participant_curvatures` for the
    participants in the slots every step of a shielded decision. A lane given another shape
    gets its geometry worked out anew."""

    def route(self, lane: str) -> RouteShape | None:
        """The lane's :class:`RouteShape`, or None for a lane this map does not describe."""
        shape = self.get(lane)
        if shape is None:
            return None
        routes: dict[str, tuple[FloatArray, RouteShape]] = self.__dict__.setdefault("_routes", {})
        cached = routes.get(lane)
        if cached is None or cached[0] is not shape:
            cached = routes[lane] = (shape, route_shape(shape))
        return cached[1]


def participant_curvatures(lane_shapes: Mapping[str, FloatArray], lanes: Sequence[str],
                           observations: FloatArray, kinds: Sequence[str]) -> FloatArray:
    """Signed curvature 1/R [1/m] of perceived participants (the R of f_other), from the lane the
    map matches each to and its observed position (rows ``[p_x, p_y, ...]``): 0 on lanes
    ``lane_shapes`` does not describe, and for pedestrians. With :class:`LaneShapes` (the world's)
    each lane's geometry is worked out once, not once a participant a step."""
    kappa = np.zeros(len(lanes))
    for k, lane in enumerate(lanes):
        if kinds[k] == "pedestrian":
            continue
        shape = (lane_shapes.route(str(lane)) if isinstance(lane_shapes, LaneShapes)
                 else lane_shapes.get(str(lane)))
        if shape is not None:
            kappa[k] = route_curvature(shape, float(observations[k][0]), float(observations[k][1]))
    return kappa
