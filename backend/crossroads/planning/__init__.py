"""The general static path planner (SPEC §1): candidate routes and their speed references."""

from crossroads.planning.routes import (
    ENTRANCE_LENGTH_M,
    EXIT_LENGTH_M,
    CandidatePath,
    PathProjection,
    PlanningError,
    Refusal,
    TaskPlan,
    build_candidate,
    plan_candidates,
    plan_task,
    select_movements,
)
from crossroads.planning.speeds import (
    SPEED_MODES,
    SpeedMode,
    inside_speed,
    outside_speed,
    pass_speed,
    speed_profile,
    stop_speed,
)

__all__ = [
    "ENTRANCE_LENGTH_M",
    "EXIT_LENGTH_M",
    "SPEED_MODES",
    "CandidatePath",
    "PathProjection",
    "PlanningError",
    "Refusal",
    "SpeedMode",
    "TaskPlan",
    "build_candidate",
    "inside_speed",
    "outside_speed",
    "pass_speed",
    "plan_candidates",
    "plan_task",
    "select_movements",
    "speed_profile",
    "stop_speed",
]
