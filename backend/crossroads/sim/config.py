"""What a world is made of: the intersection, the ego's task and start, the lights and the traffic.

Plain frozen dataclasses (the simulation's internal record). Users write scenarios
(:mod:`crossroads.scenario.spec`, validated by pydantic), which turn into a WorldConfig.
The seed is not part of the config: every episode of one config gets its own seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from crossroads.constants import (
    ALL_RED_S,
    CYCLE_S,
    GREEN_S,
    PASS_SPEED_FACTOR_OUTSIDE,
    V_LIMIT_MPS,
    YELLOW_S,
)
from crossroads.network.road import Turn
from crossroads.sim.abnormal import AbnormalConfig
from crossroads.sim.traffic import TrafficDemand

DEFAULT_WARMUP_S = 60.0  # [s] SUMO runs this long before the ego enters, to populate the junction
# [s] an episode that has not ended by then is a timeout: two signal cycles (2 × 103 s). The
# paper counts a pass with no time limit; a driver that waits its turn meets a red of up to 40 s,
# then at worst a green spent behind a queue that only clears at the next one: two whole cycles
# leave every such wait its chance, where a 60 s limit turned waiting into failure.
DEFAULT_TIMEOUT_S = 2.0 * CYCLE_S
# [s] participants other than the ego standing this long inside the junction are removed
# (sim/gridlock.py); None turns the breaker off. The longest wait inside the junction that is not
# a gridlock: a left-turner that entered at the start of a green and yielded through all of it
# (to oncoming traffic, or to a crossing's walk) leaves in the yellow and the all-red; 10 s more
# is the margin. (30 s removed right-turners yielding to a walk in light traffic; 60 s removed
# left-turners just before the yellow let them go.)
DEFAULT_GRIDLOCK_STAND_S: float | None = GREEN_S + YELLOW_S + ALL_RED_S + 10.0
DEFAULT_START_DISTANCE_M = 40.0  # [m] ego's start, measured back from the stop line


@dataclass(frozen=True)
class EgoStart:
    """Where and how the ego enters: on an entrance lane, some distance before the stop line."""

    distance_to_stop_line_m: float = DEFAULT_START_DISTANCE_M  # [m]
    speed_mps: float = PASS_SPEED_FACTOR_OUTSIDE * V_LIMIT_MPS  # [m/s] default: the pass-mode cruise speed, 0.8·V_limit
    entrance_lane: str | None = None  # lane id; default: the entrance lane of the first candidate


@dataclass(frozen=True)
class SignalStart:
    """The traffic light's state when the ego enters (after the warm-up).

    Either an exact ``phase_index`` (``elapsed_s`` spent in that phase), or, when it is None,
    the colour the ego's own movement shows (``elapsed_s`` spent in that colour), found in the
    junction's program by :func:`crossroads.sim.signals.phase_for_light`: ``ego_light="green"``
    is green for the ego on any net, where phase 0 is so only on the catalogue's.
    """

    phase_index: int | None = None  # index into the tlLogic's phases; None: by ``ego_light``
    elapsed_s: float = 0.0  # [s] time already spent in that phase (or colour)
    ego_light: Literal["green", "yellow", "red"] = "green"  # used when phase_index is None
    program_id: str | None = None  # the tlLogic's programID; None: the one SUMO runs (last loaded)


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
    rho: float | None = None  # ρ of the Bezier candidate paths; None: chosen per candidate
    gridlock_stand_s: float | None = DEFAULT_GRIDLOCK_STAND_S  # [s] sim/gridlock.py; None: off
    standing_ego_courtesy: bool = True  # pedestrians, cyclists and drivers stop for a standing ego (sim/courtesy.py)
    junction_clearing: bool = True  # vehicles caught inside the junction by the end of their green clear it (sim/clearing.py)
    let_out: bool = True  # drivers entering on green let those caught inside out first (sim/letting_out.py)
    junction_lane_changes: bool = False  # SUMO's drivers may change lanes inside the junction (an instant jump)
