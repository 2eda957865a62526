"""What a scenario asks of its network, checked against the network before anything is stored.

The scenario format leaves to the world what needs the built network: whether ``approach`` and
``ego.entrance_lane`` exist, whether the task can be driven from there, whether the start distance
fits on the road before the stop line (``sim.start``, the world's own rule), whether ``lights``
(an exact phase, or the ego's colour, and the program) are in the signal program. A batch would
only find out in its workers, as one error per episode; the API (a 422 naming the field),
``crossroads run`` and ``crossroads evaluate`` (before any batch starts) check them here instead.
The junction is read through :func:`~crossroads.intersections.resolve.open_junction` and the signal
program through a cache of its own, so a check after the first costs next to nothing.
"""

from __future__ import annotations

import json
import logging
from functools import lru_cache
from pathlib import Path
from typing import Any

from crossroads.intersections.resolve import NetworkNotFoundError, open_junction
from crossroads.network.junction import JunctionError
from crossroads.network.road import Approach, Junction
from crossroads.planning import PlanningError, plan_candidates
from crossroads.planning.internal_lanes import internal_lane_offsets, offset_warning
from crossroads.scenario.spec import ScenarioSpec, net_path
from crossroads.sim.signals import (
    SignalError,
    TlProgram,
    colours_of,
    movement_link,
    phase_for_light,
    read_all_programs,
    read_program,
)
from crossroads.sim.abnormal import injection_lane, opposite_approach
from crossroads.sim.start import start_problem
from crossroads.validation import SpecError

Problems = list[tuple[str, str]]

log = logging.getLogger(__name__)


@lru_cache(maxsize=64)
def _program_cached(net_file: Path, mtime_ns: int, tl_id: str, program_id: str | None) -> TlProgram:
    return read_program(net_file, tl_id, program_id)


def signal_program(net_file: str | Path, tl_id: str, program_id: str | None = None) -> TlProgram:
    """A traffic light's program (cached while its network file is unchanged): ``program_id``,
    or the one SUMO runs."""
    net = Path(net_file)
    return _program_cached(net, net.stat().st_mtime_ns, tl_id, program_id)


def program_json(net_file: str | Path, tl_id: str) -> dict[str, Any] | None:
    """The signal program for the editor (phase index → duration and state); None if unreadable."""
    try:
        program = signal_program(net_file, tl_id)
    except (SignalError, OSError):
        return None
    return {"tl_id": program.tl_id, "program_id": program.program_id, "offset_s": program.offset_s,
            "phases": [{"duration_s": p.duration_s, "state": p.state} for p in program.phases]}


def _junction_of(spec: ScenarioSpec, base_dir: Path | None) -> tuple[Junction | None, Problems]:
    if isinstance(spec.intersection, str):
        ref: str | Path = spec.intersection
        junction_id, field = None, "intersection"
    else:
        ref = net_path(spec, base_dir)  # type: ignore[assignment]
        junction_id = spec.intersection.junction
        field = "intersection.junction" if junction_id else "intersection.net"
    try:
        return open_junction(ref, junction_id), []
    except (NetworkNotFoundError, JunctionError, SpecError, OSError) as exc:
        return None, [(field, str(exc))]


def _approach_of(spec: ScenarioSpec, junction: Junction) -> tuple[Approach | None, Problems]:
    if spec.approach is None:
        return junction.default_approach(), []
    try:
        return junction.approach(spec.approach), []
    except KeyError:
        known = ", ".join(a.id for a in junction.approaches)
        return None, [("approach", f"junction {junction.id!r} has no approach {spec.approach!r}; "
                                   f"its approaches: {known}")]


def _ego_problems(spec: ScenarioSpec, junction: Junction, approach: Approach) -> Problems:
    """The start lane exists on the approach, leads where the task goes, and is long enough."""
    try:
        candidates = plan_candidates(junction, spec.task, approach=approach, rho=spec.rho)
    except PlanningError as exc:
        return [("task", f"no {spec.task} path from approach {approach.id!r}: {exc}")]
    lane_id = spec.ego.entrance_lane or candidates[0].entrance_lane
    lanes = {lane.id: lane for lane in approach.entrance_lanes}
    if lane_id not in lanes:
        return [("ego.entrance_lane", f"{lane_id!r} is not an entrance lane of approach "
                                      f"{approach.id!r}; its entrance lanes: {', '.join(lanes)}")]
    turns = approach.turns_of(lane_id)
    if spec.task not in turns:
        able = [lane for lane in lanes if spec.task in approach.turns_of(lane)]
        return [("ego.entrance_lane", f"lane {lane_id!r} does not lead {spec.task} (it leads "
                                      f"{', '.join(sorted(turns)) or 'nowhere'}); lanes that do: "
                                      f"{', '.join(able)}")]
    # the start must fit on the road before the stop line (sim.start: the world's own rule)
    problem = start_problem(junction, lane_id, spec.ego.start_distance_m)
    return [] if problem is None else [("ego.start_distance_m", problem)]


def _light_problems(spec: ScenarioSpec, junction: Junction, approach: Approach | None) -> Problems:
    lights = spec.lights
    try:
        program = signal_program(junction.net_file, junction.tl_id, lights.program)
    except SignalError as exc:
        return [("lights.program" if lights.program is not None else "intersection", str(exc))]
    if lights.phase is not None:
        phase, n = lights.phase, len(program.phases)
        if phase >= n:
            return [("lights.phase", f"the signal program of {junction.tl_id!r} has {n} phases: "
                                     f"0 to {n - 1}")]
        duration = program.phases[phase].duration_s
        if lights.elapsed_s >= duration:
            return [("lights.elapsed_s", f"phase {phase} lasts {duration:g} s: the time already "
                                         f"spent in it must be below that")]
        return []
    if approach is None:
        return []  # the approach is wrong already: no movement to find the ego's light of
    try:  # the world's start lane: the scenario's, or the first candidate's
        lane_id = spec.ego.entrance_lane or plan_candidates(
            junction, spec.task, approach=approach, rho=spec.rho)[0].entrance_lane
    except PlanningError:
        return []  # no path for the task: _ego_problems says so
    try:
        link = movement_link(approach, spec.task, lane_id)
    except SignalError as exc:
        return [("task", str(exc))]
    try:
        phase_for_light(program, link, lights.ego_light, lights.elapsed_s)
    except SignalError as exc:
        if "time already spent" in str(exc):
            return [("lights.elapsed_s", str(exc))]
        return [("lights.ego", str(exc) + _other_programs_hint(junction, program, link, lights.ego_light))]
    return []


def _other_programs_hint(junction: Junction, program: TlProgram, link: int, light: str) -> str:
    """Which other programs of the light show ``light`` on ``link`` (a net may hold a program per
    time of day, or per stage of a game), for a scenario to choose with ``lights.program``."""
    try:
        others = read_all_programs(junction.net_file).get(junction.tl_id, {})
    except SignalError:
        return ""
    showing = [pid for pid, p in others.items() if pid != program.program_id
               and link < p.n_links and light in colours_of(p, link)]
    if not showing:
        return ""
    return f"; program(s) {', '.join(repr(pid) for pid in showing)} show it {light} (lights.program)"


def _injection_problems(spec: ScenarioSpec, junction: Junction, approach: Approach) -> Problems:
    """Injected over-speeders need a lane going straight on the opposite approach."""
    injection = spec.abnormal.injection
    if injection is None or injection.count == 0 or injection_lane(junction, approach) is not None:
        return []
    opposite = opposite_approach(junction, approach)
    return [("abnormal.injection", f"the approach opposite {approach.id!r} ({opposite.id!r}) has no lane "
                                   "going straight, where injected over-speeders would come from")]


def network_problems(spec: ScenarioSpec, base_dir: str | Path | None = None) -> Problems:
    """Every field of ``spec`` its network contradicts, as ``(field, message)`` pairs; a
    ``{net: ...}`` path is taken relative to ``base_dir`` (see ``scenario.spec.net_path``)."""
    junction, problems = _junction_of(spec, None if base_dir is None else Path(base_dir))
    if junction is None:
        return problems
    approach, problems = _approach_of(spec, junction)
    if approach is not None:
        problems = _ego_problems(spec, junction, approach) + _injection_problems(spec, junction, approach)
    return problems + _light_problems(spec, junction, approach)


def internal_lane_warning(spec: ScenarioSpec, base_dir: str | Path | None = None) -> str | None:
    """A warning when SUMO's internal lanes of the ego's movements (its approach, its task) run
    further from their candidate paths than half the ego's width (``planning.internal_lanes``):
    not an error, the scenario runs, but SUMO sees the ego elsewhere than it drives. None when
    they do not, or when the network has problems of its own (:func:`network_problems` names them)."""
    junction, _ = _junction_of(spec, None if base_dir is None else Path(base_dir))
    if junction is None:
        return None
    approach, _ = _approach_of(spec, junction)
    if approach is None:
        return None
    offsets = internal_lane_offsets(junction, rho=spec.rho, approach=approach, turn=spec.task)
    name = spec.intersection if isinstance(spec.intersection, str) else net_label(junction.net_file)
    return offset_warning(offsets, f"{name} ({spec.task} from {approach.id})")


def uploaded_name(net_file: str | Path) -> str | None:
    """The name a studio upload was uploaded under: uploads are stored as ``<sha256>.net.xml`` with
    ``<sha256>.json`` beside them keeping it (``api.routes.uploads``). None for any other file, or
    when the record is missing or unreadable."""
    path = Path(net_file)
    try:
        record = json.loads(path.with_name(path.name.removesuffix(".net.xml") + ".json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    name = record.get("name") if isinstance(record, dict) else None
    return name if isinstance(name, str) and name else None


def net_label(net_file: str | Path) -> str:
    """How a warning names a network file: its file name; for a studio upload the name it was
    uploaded under and the digest's start, so a report read later says which network the user meant."""
    path = Path(net_file)
    name = uploaded_name(path)
    return path.name if name is None else f"{name} (upload {path.name[:12]})"


def batch_warnings(spec: ScenarioSpec, base_dir: str | Path | None = None) -> list[str]:
    """What a batch of ``spec`` keeps beside its results: :func:`internal_lane_warning` of the
    network as it is now (a report read later must say it, whatever the network has become).

    Empty when there is nothing to say, and when measuring fails on an odd network (a degenerate
    lane or path shape raises ValueError, as PlanningError and JunctionError do): a warning must
    never keep a batch from being created. Anything else is no odd shape and is raised; what is
    wrong with the network itself, :func:`network_problems` has rejected before.
    """
    try:
        warning = internal_lane_warning(spec, base_dir)
    except ValueError as exc:
        log.warning("%s: could not measure the internal lanes against the candidate paths: %s",
                    spec.name, exc)
        return []
    return [] if warning is None else [warning]
