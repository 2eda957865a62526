"""Traffic-light programs: read from the net, evaluated by pure functions, applied in SUMO.

A static SUMO program is a cycle of phases, each a duration [s] and a state string with one
character per link index (SUMO: ``G``/``g`` green, ``y``/``Y`` yellow, ``r``/``R``/``s``/``u`` no
go, ``o``/``O`` signal off). SUMO's ``offset`` shifts the cycle: at simulation time ``t`` the
program is at cycle position ``(t - offset) mod cycle`` (measured against SUMO 1.28).

The ego sees one link (its connection's ``tl_link_index``): :func:`light_at` gives its colour and
how long that colour lasts (``t_y`` of the yellow logic, SPEC §7, when the colour is yellow).

A net may define several programs for one light (a city net's ``"0"`` and ``"utopia"``); SUMO
runs the last one loaded, and so does :func:`read_program` unless asked for another by its
program id. :func:`apply_start` switches SUMO to the program held, and :func:`live_light` refuses
to read a phase index past it.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Literal

from crossroads.network.netxml import open_net

if TYPE_CHECKING:  # only for type hints: signals.py itself never needs SUMO running
    from crossroads.network.road import Approach
    from crossroads.sim.sumo import SumoSession

Light = Literal["green", "yellow", "red"]

# SUMO signal characters → what a driver must do. "o"/"O" (signal off) drive with care: green.
# "u" (red+yellow, about to turn green) still forbids to go: red. "s" (stop sign): red.
_LIGHT_OF: dict[str, Light] = {
    "G": "green", "g": "green", "o": "green", "O": "green",
    "y": "yellow", "Y": "yellow",
    "r": "red", "R": "red", "s": "red", "u": "red",
}


class SignalError(ValueError):
    """The net has no such program, or a program/link is malformed."""


def light_of(char: str) -> Light:
    """Colour of one SUMO state character."""
    try:
        return _LIGHT_OF[char]
    except KeyError:
        raise SignalError(f"unknown SUMO signal state {char!r}") from None


@dataclass(frozen=True)
class Phase:
    duration_s: float  # [s]
    state: str  # one character per link index

    def light(self, link_index: int) -> Light:
        if not 0 <= link_index < len(self.state):
            raise SignalError(f"link index {link_index} outside 0..{len(self.state) - 1}")
        return light_of(self.state[link_index])


@dataclass(frozen=True)
class TlProgram:
    """One static program of a traffic light (SUMO's ``<tlLogic>``)."""

    tl_id: str
    program_id: str
    offset_s: float  # [s] SUMO's offset: cycle position 0 is reached at t = offset
    phases: tuple[Phase, ...]

    def __post_init__(self) -> None:
        if not self.phases:
            raise SignalError(f"traffic light {self.tl_id!r}: program without phases")
        n = len(self.phases[0].state)
        if any(len(p.state) != n for p in self.phases):
            raise SignalError(f"traffic light {self.tl_id!r}: phases of different link counts")
        if any(p.duration_s <= 0 for p in self.phases):
            raise SignalError(f"traffic light {self.tl_id!r}: phase with non-positive duration")

    @property
    def cycle_s(self) -> float:
        return sum(p.duration_s for p in self.phases)

    @property
    def n_links(self) -> int:
        return len(self.phases[0].state)

    def phase_start_s(self, index: int) -> float:
        """Cycle position [s] at which phase ``index`` begins."""
        return sum(p.duration_s for p in self.phases[:index])


@dataclass(frozen=True)
class PhaseAt:
    """Where a program is at some instant."""

    index: int
    elapsed_s: float  # [s] time spent in this phase
    remaining_s: float  # [s] until this phase ends


@dataclass(frozen=True)
class LightAt:
    """What one link shows at some instant."""

    light: Light
    remaining_s: float  # [s] until the colour changes (math.inf if it never does)
    phase: PhaseAt


def read_all_programs(net_file: str | Path) -> dict[str, dict[str, TlProgram]]:
    """Every ``<tlLogic>`` of a net: by traffic-light id, then by program id, in file order.

    A net may hold several programs of one light (a city net's ``"0"`` and ``"utopia"``); SUMO
    runs the last one it loads (:func:`running_program_id`).
    """
    programs: dict[str, dict[str, TlProgram]] = {}
    try:
        with open_net(net_file) as f:
            logics = list(_tl_logics(f))
        for el in logics:
            tl_id, program_id = el.get("id", ""), el.get("programID", "0")
            phases = tuple(
                Phase(float(p.get("duration", "0")), p.get("state", "")) for p in el.iter("phase")
            )
            by_id = programs.setdefault(tl_id, {})
            by_id.pop(program_id, None)  # a later definition of the same program replaces it, last
            by_id[program_id] = TlProgram(tl_id, program_id, float(el.get("offset", "0")), phases)
    except (ET.ParseError, OSError, ValueError) as exc:
        raise SignalError(f"cannot read traffic-light programs of {net_file}: {exc}") from exc
    return programs


def _tl_logics(f: IO[bytes]) -> Iterator[ET.Element]:
    """Every ``<tlLogic>`` element of a net file, in file order (everything else is dropped as
    it is read)."""
    for _, el in ET.iterparse(f, events=("end",)):
        if el.tag == "tlLogic":
            yield el
        elif el.tag in ("edge", "junction", "connection"):
            el.clear()


def running_program_id(programs: dict[str, TlProgram]) -> str:
    """The program SUMO runs of one light's programs (as :func:`read_all_programs` gives them):
    the last one loaded (checked against SUMO 1.28 in the tests)."""
    return next(reversed(programs))


def read_programs(net_file: str | Path) -> dict[str, TlProgram]:
    """The program SUMO runs of every traffic light of a net, by traffic-light id."""
    return {tl_id: by_id[running_program_id(by_id)]
            for tl_id, by_id in read_all_programs(net_file).items()}


def read_program(net_file: str | Path, tl_id: str, program_id: str | None = None) -> TlProgram:
    """One program of one traffic light (e.g. ``junction.tl_id``): ``program_id``, or by default
    the one SUMO runs (the last loaded)."""
    programs = read_all_programs(net_file)
    if tl_id not in programs:
        known = ", ".join(sorted(programs)) or "none"
        raise SignalError(f"{net_file} has no tlLogic {tl_id!r}; it has: {known}")
    by_id = programs[tl_id]
    if program_id is None:
        return by_id[running_program_id(by_id)]
    if program_id not in by_id:
        raise SignalError(f"traffic light {tl_id!r} has no program {program_id!r}; its programs: "
                          f"{', '.join(repr(k) for k in by_id)}")
    return by_id[program_id]


def phase_at(program: TlProgram, t_s: float, offset_s: float | None = None) -> PhaseAt:
    """Phase of a program at time ``t_s`` [s], SUMO's semantics: position = (t − offset) mod cycle.

    ``offset_s`` defaults to the program's own offset.
    """
    offset = program.offset_s if offset_s is None else offset_s
    pos = (t_s - offset) % program.cycle_s
    start = 0.0
    for i, ph in enumerate(program.phases):
        end = start + ph.duration_s
        # A tiny tolerance so that float sums of 0.1 s steps land in the phase SUMO is in.
        if pos < end - 1e-9:
            return PhaseAt(i, pos - start, end - pos)
        start = end
    last = len(program.phases) - 1  # pos ≈ cycle within rounding: the cycle starts again
    return PhaseAt(0, 0.0, program.phases[0].duration_s) if last >= 0 else PhaseAt(0, 0.0, 0.0)


def remaining_of_light(program: TlProgram, phase: PhaseAt, link_index: int) -> float:
    """How long the link keeps its current colour [s]: the rest of this phase plus every following
    phase of the same colour; ``math.inf`` when the colour never changes (e.g. a right turn that
    is always green)."""
    if not 0 <= link_index < program.n_links:
        raise SignalError(
            f"link index {link_index} outside 0..{program.n_links - 1} of {program.tl_id!r}"
        )
    colour = program.phases[phase.index].light(link_index)
    total = phase.remaining_s
    n = len(program.phases)
    for k in range(1, n):
        ph = program.phases[(phase.index + k) % n]
        if ph.light(link_index) != colour:
            return total
        total += ph.duration_s
    return math.inf


def light_at(program: TlProgram, link_index: int, t_s: float,
             offset_s: float | None = None) -> LightAt:
    """Colour of one link at time ``t_s`` and how long it lasts (``t_y`` when yellow)."""
    ph = phase_at(program, t_s, offset_s)
    return LightAt(program.phases[ph.index].light(link_index),
                   remaining_of_light(program, ph, link_index), ph)


def offset_for(program: TlProgram, t_s: float, phase_index: int, elapsed_s: float = 0.0) -> float:
    """The program offset that puts phase ``phase_index`` at ``elapsed_s`` [s] at time ``t_s``."""
    if not 0 <= phase_index < len(program.phases):
        raise SignalError(f"phase {phase_index} outside the {len(program.phases)} phases")
    if not 0.0 <= elapsed_s < program.phases[phase_index].duration_s:
        raise SignalError(f"elapsed {elapsed_s} s outside phase {phase_index}")
    return (t_s - program.phase_start_s(phase_index) - elapsed_s) % program.cycle_s


def _check_running(session: SumoSession, program: TlProgram, index: int, state: str) -> None:
    """SUMO's phase ``index`` and ``state`` belong to ``program``; otherwise SUMO runs another
    program of the light (never index past the one held)."""
    if 0 <= index < len(program.phases) and len(state) == program.n_links:
        return
    raise SignalError(
        f"SUMO runs phase {index} ({len(state)} links) of traffic light {program.tl_id!r}, but its "
        f"program {program.program_id!r} has {len(program.phases)} phases of {program.n_links} links: "
        f"SUMO runs program {session.tl_program(program.tl_id)!r}, not the one read")


def live_light(session: SumoSession, program: TlProgram, link_index: int, *,
               state: str | None = None) -> LightAt:
    """The link's colour and its remaining time as SUMO has them now (the running truth).

    ``state``: SUMO's state string of the light, when the caller has read it already this step.
    Raises :class:`SignalError` when SUMO runs another program than ``program``.
    """
    if state is None:
        state = session.tl_state(program.tl_id)
    index = session.tl_phase(program.tl_id)
    _check_running(session, program, index, state)
    remaining = session.tl_time_to_switch_s(program.tl_id)
    ph = PhaseAt(index, program.phases[index].duration_s - remaining, remaining)
    return LightAt(light_of(state[link_index]), remaining_of_light(program, ph, link_index), ph)


def apply_start(session: SumoSession, program: TlProgram, phase_index: int,
                elapsed_s: float = 0.0) -> float:
    """Put SUMO's light in ``phase_index`` of ``program`` with ``elapsed_s`` [s] already spent,
    from now on (switching the light to ``program`` first when it runs another one).

    Returns the equivalent offset [s] for :func:`phase_at` / :func:`light_at`. Later cycles keep
    the program's durations (``setPhaseDuration`` only changes the current phase).
    """
    offset = offset_for(program, session.time_s, phase_index, elapsed_s)
    if session.tl_program(program.tl_id) != program.program_id:
        session.set_tl_program(program.tl_id, program.program_id)
    session.set_tl_phase(program.tl_id, phase_index)
    session.set_tl_phase_duration(program.tl_id,
                                  program.phases[phase_index].duration_s - elapsed_s)
    return offset


# --- the ego's light ------------------------------------------------------------------------------


def movement_link(approach: Approach, task: str, lane_id: str) -> int:
    """The link index of the ego's movement: ``task`` from ``lane_id`` of ``approach``; where
    that lane has no signalised connection for the task, the first signalised one of the task."""
    conns = approach.connections_for(task)  # type: ignore[arg-type]
    for c in conns:
        if c.from_lane == lane_id and c.tl_link_index is not None:
            return c.tl_link_index
    for c in conns:
        if c.tl_link_index is not None:
            return c.tl_link_index
    raise SignalError(f"no signalised {task} movement from approach {approach.id!r}")


def colours_of(program: TlProgram, link_index: int) -> tuple[Light, ...]:
    """The colours a link shows over the cycle, each once, in phase order."""
    seen: dict[Light, None] = {}
    for ph in program.phases:
        seen.setdefault(ph.light(link_index), None)
    return tuple(seen)


def phase_for_light(program: TlProgram, link_index: int, light: Light,
                    elapsed_s: float = 0.0) -> tuple[int, float]:
    """``(phase index, time spent in it [s])`` at which the link has shown ``light`` for
    ``elapsed_s`` [s]: what ``lights: {ego: green}`` means on any program.

    The colour's stretch is the first one of the cycle (in phase order) that begins with a change
    to that colour, so the link shows the whole stretch: green from its first green second, not
    from the middle of a green that began in the previous cycle. A stretch may span several phases
    (SUMO's ``G`` then ``g``); ``elapsed_s`` walks through them. Raises :class:`SignalError` when
    the link never shows ``light`` or the stretch is not that long.
    """
    n = len(program.phases)
    lights = [ph.light(link_index) for ph in program.phases]
    if light not in lights:
        raise SignalError(f"link {link_index} of traffic light {program.tl_id!r} (program "
                          f"{program.program_id!r}) is never {light}: it shows "
                          f"{', '.join(colours_of(program, link_index))}")
    starts = [i for i in range(n) if lights[i] == light and lights[i - 1] != light]
    start = starts[0] if starts else 0  # the link shows nothing else: the cycle is one stretch
    total = 0.0
    for k in range(n):
        i = (start + k) % n
        if lights[i] != light:
            break
        duration = program.phases[i].duration_s
        if elapsed_s < total + duration:
            return i, elapsed_s - total
        total += duration
    raise SignalError(f"link {link_index} of traffic light {program.tl_id!r} is {light} for "
                      f"{total:g} s at a time: the time already spent in it must be below that")
