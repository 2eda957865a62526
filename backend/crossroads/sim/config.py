"""What a world is made of: the intersection, the ego's task and start, the lights and the traffic.

Plain frozen dataclasses (the simulation's internal record). Users write scenarios
(:mod:`crossroads.evaluation.scenario`, validated by pydantic), which turn into a WorldConfig.
The seed is not part of the config: every episode of one config gets its own seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from crossroads.constants import PASS_SPEED_FACTOR_OUTSIDE, RHO_BEZIER, V_LIMIT_MPS
from crossroads.network.model import Turn
from crossroads.sim.abnormal import AbnormalConfig
from crossroads.sim.traffic import TrafficDemand

DEFAULT_WARMUP_S = 60.0  # [s] SUMO runs this long before the ego enters, to populate the junction
DEFAULT_TIMEOUT_S = 60.0  # [s] an episode that has not ended by then is a timeout
DEFAULT_START_DISTANCE_M = 40.0  # [m] ego's start, measured back from the stop line


@dataclass(frozen=True)
class EgoStart:
    """Where and how the ego enters: on an entrance lane, some distance before the stop line."""

    distance_to_stop_line_m: float = DEFAULT_START_DISTANCE_M  # [m]
    speed_mps: float = PASS_SPEED_FACTOR_OUTSIDE * V_LIMIT_MPS  # [m/s] default: the pass-mode cruise speed, 0.8·V_limit
    entrance_lane: str | None = None  # lane id; default: the entrance lane of the first candidate


@dataclass(frozen=True)
class SignalStart:
    """The traffic light's state when the ego enters (after the warm-up)."""

    phase_index: int = 0  # index into the tlLogic's phases (0: the ego's axis green)
    elapsed_s: float = 0.0  # [s] time already spent in that phase


@dataclass(frozen=True)
class WorldConfig:
    """Everything that defines a world, apart from the seed."""

    net_file: Path
    task: Turn
    junction_id: str | None = None  # default: the traffic light nearest the net's centre
    approach: str | None = None  # incoming edge id; default: the approach from the south
    demand: TrafficDemand = field(default_factory=TrafficDemand)
    abnormal: AbnormalConfig = field(default_factory=AbnormalConfig)
    signal_start: SignalStart = field(default_factory=SignalStart)
    ego_start: EgoStart = field(default_factory=EgoStart)
    warmup_s: float = DEFAULT_WARMUP_S  # [s]
    timeout_s: float = DEFAULT_TIMEOUT_S  # [s] of ego time
    perception_noise: bool = True  # Gaussian noise of SPEC §3 on the observations
    rho: float = RHO_BEZIER  # ρ of the Bezier candidate paths
