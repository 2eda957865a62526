"""One episode: a controller drives the ego in a world until an outcome, with an optional trace.

The outcome is one of passed, collision, red_light, off_road, timeout (judged by the world on the
true footprints). Travel time is measured from the ego's front bumper crossing the stop line to
the step it counts as having left the intersection onto its target road (SPEC §8).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from crossroads.evaluation.sumo_driver import SumoDriverPolicy
from crossroads.evaluation.near_miss import NearMissTracker
from crossroads.evaluation.trace import TraceRecorder
from crossroads.idc.controller import Controller
from crossroads.sim.outcome import Outcome
from crossroads.sim.world import World


@dataclass(frozen=True)
class EpisodeResult:
    """What an episode came to; JSON-ready through :meth:`to_json`."""

    seed: int
    outcome: str  # passed | collision | red_light | off_road | timeout
    steps: int
    time_s: float  # [s] of ego time
    travel_time_s: float | None  # [s] stop line → exit; only for passed episodes
    min_distance_m: float  # [m] closest centre distance to any other participant
    detail: str = ""
    collided_with: str | None = None  # vehicle | cyclist | pedestrian
    events: list[dict[str, Any]] = field(default_factory=list)  # mode, path and shield switches, ...
    # a timeout behind a participant that barred every path the whole episode (sim/blocking.py)
    blocked_by: dict[str, Any] | None = None
    # how close it came to failing (evaluation/near_miss.py); None: not measured or nothing near
    min_gap_m: float | None = None  # [m] smallest footprint gap to one closing in (<= 0: touching)
    min_ttc_s: float | None = None  # [s] shortest time to collision with one ahead
    red_stop_margin_m: float | None = None  # [m] driving on red: distance to the line − braking distance

    @property
    def passed(self) -> bool:
        return self.outcome == "passed"

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def run_episode(
    world: World,
    controller: Controller,
    seed: int,
    *,
    recorder: TraceRecorder | None = None,
    scenario_name: str = "",
) -> EpisodeResult:
    """Reset ``world`` with ``seed`` and let ``controller`` drive until an outcome.

    A :class:`SumoDriverPolicy` hands the ego to SUMO's own driver instead (policy ``sumo``).
    With a ``recorder``, every step (and the final state) goes into its trace.
    """
    sumo_drives = isinstance(controller, SumoDriverPolicy)
    observation = world.reset(seed, sumo_driver=controller.driver if sumo_drives else None)
    controller.reset(world.candidates)
    if recorder is not None:
        recorder.start(world, seed, scenario=scenario_name)
    events: list[dict[str, Any]] = []
    near_miss = NearMissTracker()
    near_miss.update(observation, world.truth)
    last_mode = last_path = None
    last_shield = False  # a shielded run starts with the shield off: its first event is it braking
    outcome: Outcome | None = None
    steps = 0
    while outcome is None:
        decision = controller.decide(observation)
        if decision.speed_mode != last_mode:
            events.append({"t": round(observation.time_s, 2), "event": "speed_mode",
                           "value": decision.speed_mode})
            last_mode = decision.speed_mode
        if decision.path_index != last_path:
            events.append({"t": round(observation.time_s, 2), "event": "path",
                           "value": int(decision.path_index)})
            last_path = decision.path_index
        if decision.shield_braking is not None and decision.shield_braking != last_shield:
            events.append({"t": round(observation.time_s, 2), "event": "shield_braking",
                           "value": decision.shield_braking})
            last_shield = decision.shield_braking
        if recorder is not None:
            recorder.record(observation, decision, world.truth)
        observation, outcome = world.step(None if sumo_drives else decision.action)
        steps += 1
        near_miss.update(observation, world.truth)
    crossed = world.stop_line_crossed_s
    travel = outcome.time_s - crossed if outcome.kind == "passed" and crossed is not None else None
    events.extend(world.events)  # the world's own: gridlock removals
    events.sort(key=lambda e: e["t"])  # stable: a step's decisions before the world's events
    if outcome.blocked_by is not None:  # kept with the events, so the results store has it too
        events.append({"t": round(outcome.time_s, 2), "event": "blocked_by",
                       "value": outcome.blocked_by.to_json()})
    events.append({"t": round(outcome.time_s, 2), "event": "outcome", "value": outcome.kind})
    if recorder is not None:  # the trace keeps the episode's events for the playback
        recorder.finish(observation, outcome, world.truth, events=events)
    return EpisodeResult(
        seed=seed,
        outcome=outcome.kind,
        steps=steps,
        time_s=round(outcome.time_s, 3),
        travel_time_s=None if travel is None else round(travel, 3),
        min_distance_m=round(near_miss.min_distance_m, 3),
        detail=outcome.detail,
        collided_with=outcome.other_kind,
        events=events,
        blocked_by=None if outcome.blocked_by is None else outcome.blocked_by.to_json(),
        **near_miss.figures(),
    )
