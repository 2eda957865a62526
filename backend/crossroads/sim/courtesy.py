"""Pedestrians and cyclists do not walk or ride into a standing ego, the world's rule.

SUMO's pedestrians walk their crossings and walking areas whatever stands there, and its cyclists
ride their lanes without seeing a car standing across them from another lane: a car standing with
its rear over a crossing (a left-turner at its waiting point inside the junction), or half-way
into its right turn over the bike lane, is walked or ridden into, and the judge counts that as the
ego's collision. Measured (30 runs, base seed 20261206): with SUMO's own driver on the nominal left
turn of ``e_irregular_oblique``, 17 of its 20 collisions were pedestrians walking into the ego
standing at its waiting point, and on the right turn all 4 were cyclists riding into its side;
with the rule controller, 4 of the 5 collisions of the ``f_irregular_wide`` right turn were
cyclists riding into it from behind while it stood in its turn. No one does that; they stop, or
go round the car.

The rule: while the ego stands (below :data:`EGO_STANDING_MPS`), a pedestrian or cyclist whose way
ahead would bring its body into the ego's footprint stops (a cyclist at its own deceleration,
through SUMO), and goes on as soon as its way no longer comes into the ego (the ego has driven
on, or it no longer faces the car). A pedestrian looks :data:`LOOKAHEAD_S` ahead at its speed
(at least :data:`LOOKAHEAD_MIN_M`); a cyclist that far plus its braking distance, so that it can
stop in time. A cyclist held :data:`CYCLIST_STANDOFF_S` while the ego still stands goes round the car: it
is taken out of the simulation, an episode event like the gridlock breaker's — held short of a car
standing across the bike lane, it stands where that car waits to go, and the two would wait on
each other (tried: SUMO's driver then passed only once the gridlock breaker took the cyclist out,
after 138–159 s). So does a pedestrian held :data:`PEDESTRIAN_STANDOFF_S` right in front of the
still standing ego (:func:`~crossroads.sim.look_ahead.in_front`: where the ego cannot set off
without touching it), its way across grazing the car's front corner: the two wait on each other
too (SUMO's driver, which then let itself go first, crept into one standing 0.26 m from its
bumper: ``c_three_lane``'s left turn, seed 1416578486 of base seed 20261206, and the same run in
five of the six paper cases).

A moving ego: whoever it drives into is its collision, so it holds no one new, with three exceptions,
and whoever was held for it stays held, the ego moving or not, as long as its way still comes into
the ego. The exceptions: a pedestrian about to walk into the side or rear of the moving ego (its
footprint but the front :data:`SIDE_FRONT_EXCLUDED_M`) stops too, and so does a car about to drive
into its side or rear or following it (:func:`following`: near, behind it, heading its way), as
for any car ahead or crossing in front of it, and a cyclist following it about to ride into its
side or rear (a cyclist it turns across, heading a right angle or more off its way, is its own
collision). A cyclist is looked at within :data:`CYCLIST_NEAR_M` of the ego, beyond its reach:
on ``f_irregular_wide``'s right turn (the rule controller, base seed 20261206) one at 5.4 m/s, seen
only 8 m from the standing ego's centre, could no longer stop and rode into it (seed 1114790774),
and one held behind the standing ego, let go for a step as the ego set off (its way, at the speed
it had braked to, no longer came nearer), rode on into its rear quarter (seed 1120857481). Seen with SUMO's driver (base seed 20261206): on
``b_two_lane``'s left turn a right-turner merging behind it into the same exit drove up to 0.04 m
from the ego's side as the ego braked, and the ego pulling away then swung into it (seed
285310816); on ``e_irregular_oblique``'s left turn the cross street's first car, braking for the
ego clearing the junction in front of it, drove off again into its side (seed 1988177980). The
pedestrians' exception was seen with SUMO's driver on ``e_irregular_oblique``'s left turn (base
seed 20261206) in two ways: the car ahead of the standing ego taken
out by the gridlock breaker and the ego starting: a pedestrian held 0.9 m from its front corner,
released the moment the ego moved, walked into it 0.5 s later (seed 1311414304), and one walking
the crossing towards the ego's side walked into its rear quarter as the ego pulled away at 4 m/s
(seed 2084520041). No one steps into a car pulling away, nor into the side of one passing.

Drivers too: a car (not an abnormal one, which the scenario makes reckless on purpose) whose way
ahead, :data:`LOOKAHEAD_S` at its speed plus its braking distance from its front bumper, would
bring its body into the standing ego is held until its way no longer comes into the ego. SUMO's
drivers wait for a car standing across their way inside the junction as long as they heed the
junction's right of way; a vehicle clearing the junction after its green (``sim/clearing.py``) no
longer does, and no driver runs into a car standing in front of it. Inside the junction (within
:data:`SWEEP_NEAR_M` of the ego) a driver also follows its lanes' bend over that reach
(:func:`sweeping_into`): a car turning right into the exit the ego's left turn also takes, its
straight way ahead passing beside the ego standing at its waiting point, swept its front into the
ego (``b_two_lane``, seed 1882941887 of base seed 20261206).

Pure geometry below; :class:`Courtesy` applies it to a session.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import NamedTuple, TypeVar

import numpy as np

from crossroads.geometry import FloatArray, arc_lengths, footprint_points, placed_along
from crossroads.sim.gridlock import Removal
from crossroads.sim.look_ahead import CLOSING_M, WayAhead, comes_nearer, in_front
from crossroads.sim.sumo import SumoSession

EGO_STANDING_MPS = 0.5  # [m/s] below this the ego counts as standing
LOOKAHEAD_S = 1.0  # [s] how far ahead a pedestrian or cyclist looks, at its speed
LOOKAHEAD_MIN_M = 1.0  # [m] ... and at least this far (one held still looks ahead too)
PEDESTRIAN_RADIUS_M = 0.25  # [m] half a pedestrian's 0.5 m body
PEDESTRIAN_MARGIN_M = PEDESTRIAN_RADIUS_M + 0.1  # [m] ... and 0.1 m to spare
PEDESTRIAN_STANDOFF_S = 8.0  # [s] a pedestrian held this long in front of a still standing ego goes round it
CYCLIST_MARGIN_M = 0.45  # [m] half a bicycle's 0.65 m and 0.12 m to spare
CYCLIST_DECEL_MPS2 = 3.0  # [m/s²] the world's bicycles brake at this (sim/traffic.py vType)
CYCLIST_STANDOFF_S = 8.0  # [s] a cyclist held this long by a still standing ego goes round it
CAR_DECEL_MPS2 = 4.5  # [m/s²] the world's cars brake at this (sim/traffic.py vType)
CAR_SPARE_M = 0.2  # [m] kept between a held car's side and the ego, beyond half its width
SWEEP_NEAR_M = 12.0  # [m] cars inside the junction farther from the ego are not followed along their lanes
NEAR_CAR_M = 40.0  # [m] no car farther from the ego's centre is checked (14 m/s: 36 m reach)
_SAMPLE_FRACTIONS = tuple(np.linspace(0.0, 1.0, 8).tolist())  # points along the way ahead checked
_BOUND_SPARE_M = 1e-3  # [m] spare on the bound that skips a mover far from the ego (rounding only)
NEAR_M = 8.0  # [m] no pedestrian farther from the ego's centre is checked
CYCLIST_NEAR_M = 15.0  # [m] no cyclist farther from the ego's centre is checked: beyond a cyclist's
# reach at 6 m/s plus half the car (within 8 m one at 5.4 m/s could no longer stop short of the ego)
SIDE_FRONT_EXCLUDED_M = 0.5  # [m] a moving ego's front part where a pedestrian walking in is its collision
HOLDER = "courtesy"  # this rule's name among those holding a vehicle (SumoSession.hold_vehicle)


class Movers(NamedTuple):
    """Pedestrians or cyclists of one step: SUMO ids and their centres, headings, speeds."""

    ids: np.ndarray
    x: FloatArray
    y: FloatArray
    heading: FloatArray
    speed: FloatArray


def cyclist_reach(speed: FloatArray) -> FloatArray:
    """[m] how far ahead a cyclist looks: :data:`LOOKAHEAD_S` at its speed plus its braking distance."""
    speed = np.asarray(speed, dtype=float)
    return speed * LOOKAHEAD_S + speed**2 / (2.0 * CYCLIST_DECEL_MPS2)


def car_reach(speed: FloatArray) -> FloatArray:
    """[m] how far ahead of its bumper a driver looks: :data:`LOOKAHEAD_S` at its speed plus its
    braking distance."""
    speed = np.asarray(speed, dtype=float)
    return speed * LOOKAHEAD_S + speed**2 / (2.0 * CAR_DECEL_MPS2)


def moving_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                x: FloatArray, y: FloatArray, heading: FloatArray, reach: FloatArray,
                margin_m: float | FloatArray, front_m: float | None = None) -> np.ndarray:
    """Which of the movers at ``x``, ``y`` heading ``heading`` would, within ``reach`` [m] (at least
    :data:`LOOKAHEAD_MIN_M`), come into the ego's footprint widened by ``margin_m`` (one for all,
    or one each) deeper than they are now (:func:`~crossroads.sim.look_ahead.comes_nearer`). With ``front_m``, only the part of
    that footprint at most ``front_m`` ahead of the ego's centre counts (:func:`walking_into_side`).

    Checked at :data:`_SAMPLE_FRACTIONS` of each one's way ahead. Worked on Python floats, row by
    row (a step asks about a handful of movers, where numpy's per-call cost is the whole cost),
    with the arithmetic of the array formulation in its order, so the answer is the same bit for
    bit; a mover whose way ahead never comes within reach of the widened footprint's corners is
    answered without its samples."""
    xs = np.asarray(x, dtype=float).tolist()
    margins = np.asarray(margin_m, dtype=float).ravel().tolist()
    if len(margins) == 1:  # one for all
        margins = margins * len(xs)
    into = np.zeros(len(xs), dtype=bool)
    into[_rows_into(ego_x, ego_y, ego_heading, ego_length, ego_width, xs, np.asarray(y, dtype=float).tolist(),
                    np.asarray(heading, dtype=float).tolist(), np.asarray(reach, dtype=float).tolist(),
                    margins, front_m)] = True
    return into


def _rows_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
               xs: list[float], ys: list[float], headings: list[float], reaches: list[float],
               margins: list[float], front_m: float | None) -> list[int]:
    """:func:`moving_into` on Python lists: the indices of the rows that come into the ego."""
    cos_e, sin_e = math.cos(ego_heading), math.sin(ego_heading)
    into = []
    for r in range(len(xs)):
        reach_r = max(reaches[r], LOOKAHEAD_MIN_M)
        margin = margins[r]
        half_l, half_w = ego_length / 2.0 + margin, ego_width / 2.0 + margin
        radius = half_l + half_w  # at least the widened box's half-diagonal
        from_x, from_y = xs[r] - ego_x, ys[r] - ego_y
        if abs(from_x) > reach_r + radius or abs(from_y) > reach_r + radius:
            continue  # (most: far from the ego for their reach)
        step_x, step_y = math.cos(headings[r]) * reach_r, math.sin(headings[r]) * reach_r
        # the point of its way ahead nearest the ego's centre: no nearer than the widened box's
        # half-diagonal (and a spare for rounding), none of it lies in the box
        t = min(max(-(from_x * step_x + from_y * step_y) / (reach_r * reach_r), 0.0), 1.0)
        nearest_x, nearest_y = from_x + t * step_x, from_y + t * step_y
        if nearest_x * nearest_x + nearest_y * nearest_y > (math.hypot(half_l, half_w) + _BOUND_SPARE_M) ** 2:
            continue
        ahead = half_l if front_m is None else min(half_l, front_m)
        gap_now = 0.0
        for k, fraction in enumerate(_SAMPLE_FRACTIONS):
            dx, dy = (xs[r] + step_x * fraction) - ego_x, (ys[r] + step_y * fraction) - ego_y
            along = dx * cos_e + dy * sin_e
            across = -dx * sin_e + dy * cos_e
            gap = max(abs(along) - half_l, abs(across) - half_w)
            if k == 0:
                gap_now = gap
            elif (-half_l <= along <= ahead and abs(across) <= half_w) and gap < gap_now - CLOSING_M:
                # nearer than now (a driver stood 0.07 m from the ego for a minute and then drove
                # off into its corner: a_single_lane left, seed 1101115134, base seed 20261206)
                into.append(r)
                break
    return into


def walking_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                 x: FloatArray, y: FloatArray, heading: FloatArray, speed: FloatArray) -> np.ndarray:
    """:func:`moving_into` for pedestrians: :data:`LOOKAHEAD_S` at their speed."""
    return moving_into(ego_x, ego_y, ego_heading, ego_length, ego_width, x, y, heading,
                       np.asarray(speed, dtype=float) * LOOKAHEAD_S, PEDESTRIAN_MARGIN_M)


def walking_into_side(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                      x: FloatArray, y: FloatArray, heading: FloatArray, speed: FloatArray) -> np.ndarray:
    """:func:`walking_into` for a moving ego: into its sides or rear only, the front
    :data:`SIDE_FRONT_EXCLUDED_M` of the car left out (a pedestrian there is in the ego's way,
    and the ego must stop for it)."""
    return moving_into(ego_x, ego_y, ego_heading, ego_length, ego_width, x, y, heading,
                       np.asarray(speed, dtype=float) * LOOKAHEAD_S, PEDESTRIAN_MARGIN_M,
                       front_m=ego_length / 2.0 - SIDE_FRONT_EXCLUDED_M)


def riding_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                x: FloatArray, y: FloatArray, heading: FloatArray, speed: FloatArray) -> np.ndarray:
    """:func:`moving_into` for cyclists: :func:`cyclist_reach` ahead."""
    return moving_into(ego_x, ego_y, ego_heading, ego_length, ego_width, x, y, heading,
                       cyclist_reach(speed), CYCLIST_MARGIN_M)


def riding_into_side(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                     x: FloatArray, y: FloatArray, heading: FloatArray, speed: FloatArray) -> np.ndarray:
    """:func:`riding_into` a moving ego's sides or rear only, its front
    :data:`SIDE_FRONT_EXCLUDED_M` left out (a cyclist there is in the ego's way, the ego's to stop for)."""
    return moving_into(ego_x, ego_y, ego_heading, ego_length, ego_width, x, y, heading,
                       cyclist_reach(speed), CYCLIST_MARGIN_M, front_m=ego_length / 2.0 - SIDE_FRONT_EXCLUDED_M)


def sweeping_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                  way: FloatArray, length: float, width: float, reach: float, *, start_m: float = 0.0,
                  cum: FloatArray | None = None) -> bool:
    """Whether a car whose front bumper follows ``way`` ((n, 2) [m]: its lanes ahead; its front
    ``start_m`` along it, ``cum`` the way's arc lengths when known) would, within ``reach`` [m] (at
    least :data:`LOOKAHEAD_MIN_M`) along it, bring its body within :data:`CAR_SPARE_M` of the ego's
    footprint, closer than it is now (:func:`~crossroads.sim.look_ahead.comes_nearer`). Unlike :func:`driving_into` it follows the lane's bend: a
    car turning through the junction sweeps into a car standing where its straight way ahead passes
    beside it."""
    cum = arc_lengths(way) if cum is None else cum
    span = max(min(max(reach, LOOKAHEAD_MIN_M), float(cum[-1]) - start_m), 0.0)
    c, si = math.cos(ego_heading), math.sin(ego_heading)
    if start_m >= float(cum[0]):
        # its front stays within ``span`` of where it is now, its body within half a length and
        # the half-diagonal of that front: a car farther from the ego's widened box cannot come into it
        dx = float(np.interp(start_m, cum, way[:, 0])) - ego_x
        dy = float(np.interp(start_m, cum, way[:, 1])) - ego_y
        off_along = max(abs(dx * c + dy * si) - (0.5 * ego_length + CAR_SPARE_M), 0.0)
        off_across = max(abs(-dx * si + dy * c) - (0.5 * ego_width + CAR_SPARE_M), 0.0)
        if math.hypot(off_along, off_across) > (span + 0.5 * length + math.hypot(0.5 * length, 0.5 * width)
                                                + _BOUND_SPARE_M):
            return False
    s = start_m + np.linspace(0.0, span, 8)
    cx, cy, headings = placed_along(way, cum, s, length)
    px, py = footprint_points(cx, cy, headings, np.full(len(s), length), np.full(len(s), width))
    dx, dy = px - ego_x, py - ego_y
    along, across = dx * c + dy * si, -dx * si + dy * c
    # per position, its nearest footprint point's distance outside the ego's box widened by the spare
    depth = np.maximum(np.abs(along) - (0.5 * ego_length + CAR_SPARE_M),
                       np.abs(across) - (0.5 * ego_width + CAR_SPARE_M)).min(axis=1)
    return bool(comes_nearer(depth <= 0.0, depth))


def driving_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                 x: FloatArray, y: FloatArray, heading: FloatArray, speed: FloatArray,
                 length: FloatArray, width: FloatArray) -> np.ndarray:
    """:func:`moving_into` for cars (centres ``x``, ``y``): from the front bumper, :func:`car_reach`
    ahead, the body as half its width plus :data:`CAR_SPARE_M` around its way."""
    return _cars_into(ego_x, ego_y, ego_heading, ego_length, ego_width, x, y, heading, speed, length, width, None)


def _cars_into(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
               x: FloatArray, y: FloatArray, heading: FloatArray, speed: FloatArray,
               length: FloatArray, width: FloatArray, front_m: float | None) -> np.ndarray:
    """:func:`driving_into` (``front_m`` as :func:`moving_into`'s): the fronts on Python floats, as
    the array formulation computes them, the reaches :func:`car_reach`'s."""
    headings = np.asarray(heading, dtype=float).tolist()
    halves = [0.5 * v for v in np.asarray(length, dtype=float).tolist()]
    fronts_x = [v + half * math.cos(h) for v, half, h in zip(np.asarray(x, dtype=float).tolist(), halves, headings)]
    fronts_y = [v + half * math.sin(h) for v, half, h in zip(np.asarray(y, dtype=float).tolist(), halves, headings)]
    margins = (0.5 * np.asarray(width, dtype=float) + CAR_SPARE_M).tolist()
    into = np.zeros(len(headings), dtype=bool)
    into[_rows_into(ego_x, ego_y, ego_heading, ego_length, ego_width, fronts_x, fronts_y, headings,
                    car_reach(speed).tolist(), margins, front_m)] = True
    return into


class Cars(NamedTuple):
    """The cars one step may hold: :class:`Movers` plus their sizes [m]."""

    ids: np.ndarray
    x: FloatArray
    y: FloatArray
    heading: FloatArray
    speed: FloatArray
    length: FloatArray
    width: FloatArray


NO_CARS = Cars(*(np.array([]) for _ in range(7)))
MoversT = TypeVar("MoversT", Movers, Cars)


class Courtesy:
    """Holds the pedestrians, cyclists and cars that would move into the standing ego (see the
    module's rule), lets them go again, and takes out cyclists held too long; ``enabled`` False
    turns the rule off."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        self.held_pedestrians: set[str] = set()
        self.held_in_front: dict[str, float] = {}  # pedestrians held in front of the standing ego -> since [s]
        self.held_cyclists: dict[str, float] = {}  # id -> held since [s, SUMO time]
        self.held_cars: set[str] = set()

    def may_act(self, ego_speed: float, cars: Cars = NO_CARS,
                ego: tuple[float, float, float, float, float, float] | None = None) -> bool:
        """Whether :meth:`update` can change anything beyond :meth:`watch_sides`: the ego stands,
        someone is held, or one of ``cars`` follows the moving ``ego`` or is about to drive into its
        side (:func:`watched_while_moving`)."""
        return self.enabled and (ego_speed < EGO_STANDING_MPS
                                 or bool(self.held_pedestrians or self.held_cyclists or self.held_cars)
                                 or (ego is not None and bool(watched_while_moving(cars, ego))))

    def watch_sides(self, session: SumoSession, pedestrians: Movers,
                    ego: tuple[float, float, float, float, float, float], cyclists: Movers | None = None) -> None:
        """:meth:`update` while the ego moves and no one is held (``may_act`` False): only
        pedestrians and cyclists about to walk or ride into the ego's side or rear can be held."""
        if self.enabled:
            self.held_in_front = {}  # the ego moves
            self._hold_pedestrians(session, pedestrians, ego)
            if cyclists is not None and len(cyclists.ids):
                self._hold_cyclists(session, cyclists, ego)

    def _hold_pedestrians(self, session: SumoSession, pedestrians: Movers,
                          ego: tuple[float, float, float, float, float, float]) -> None:
        """Hold and release pedestrians: all walking into a standing ego; for a moving one, those
        walking into its sides and those held before whose way still comes into it."""
        if ego[3] < EGO_STANDING_MPS:
            now = _who(pedestrians, ego, walking_into)
        else:
            now = (_who(pedestrians, ego, walking_into_side)
                   | _who(_only(pedestrians, self.held_pedestrians), ego, walking_into))
        self.held_pedestrians = _apply(now, self.held_pedestrians, pedestrians.ids,
                                       session.hold_person, session.release_person)

    def update(self, session: SumoSession, pedestrians: Movers, cyclists: Movers,
               ego: tuple[float, float, float, float, float, float], cars: Cars = NO_CARS,
               car_ways: Mapping[str, WayAhead] | None = None, watched: set[str] | None = None) -> list[Removal]:
        """``ego``: its (x, y, heading, speed, length, width). Holds and releases through
        ``session`` (pedestrians by their walking speed, cyclists and cars as the vehicles they
        are, braking as SUMO lets them); returns the cyclists taken out (held
        :data:`CYCLIST_STANDOFF_S`). ``car_ways``: for the cars of ``cars`` inside the junction
        near the ego, their way ahead along their lanes (:func:`sweeping_into`). ``watched``: for a
        moving ego, :func:`watched_while_moving` of ``cars`` when the caller has it already."""
        if not self.enabled:
            return []
        self._hold_pedestrians(session, pedestrians, ego)
        # a moving ego holds no new car or cyclist; whoever it held stays until its way is clear
        standing = ego[3] < EGO_STANDING_MPS

        # a moving ego: those held before, those following it and those about to drive into its side
        if not standing and watched is None:
            watched = watched_while_moving(cars, ego)
        looked_at = None if watched is None or standing else self.held_cars | watched
        now = _who(cars if looked_at is None else _only(cars, looked_at), ego, driving_into, NEAR_CAR_M)
        if car_ways:
            now |= _sweeping(cars, car_ways, ego, looked_at)
        self.held_cars = _apply_holds(session, now, self.held_cars, cars.ids)
        self._hold_cyclists(session, cyclists, ego)
        removals = _go_round(session, self.held_cyclists, CYCLIST_STANDOFF_S, session.vehicle_lane)
        return removals + self._go_round_in_front(session, pedestrians, ego)

    def _hold_cyclists(self, session: SumoSession, cyclists: Movers,
                       ego: tuple[float, float, float, float, float, float]) -> None:
        """Hold and release cyclists: all riding into a standing ego; for a moving one, those
        following it (:func:`following`) about to ride into its sides or rear, and those held
        before whose way still comes into it."""
        if ego[3] < EGO_STANDING_MPS:
            now = _who(cyclists, ego, riding_into, CYCLIST_NEAR_M)
        else:  # held before, or following the ego into its sides or rear (one it turns across is its own)
            behind = _only(cyclists, {str(i) for i in cyclists.ids[following(ego, cyclists.x, cyclists.y,
                                                                                 cyclists.heading)]})
            now = (_who(behind, ego, riding_into_side, CYCLIST_NEAR_M)
                   | _who(_only(cyclists, set(self.held_cyclists)), ego, riding_into, CYCLIST_NEAR_M))
        kept = _apply_holds(session, now, set(self.held_cyclists), cyclists.ids)
        t = session.time_s
        self.held_cyclists = {vid: self.held_cyclists.get(vid, t) for vid in kept}

    def _go_round_in_front(self, session: SumoSession, pedestrians: Movers,
                           ego: tuple[float, float, float, float, float, float]) -> list[Removal]:
        """Takes out the pedestrians held :data:`PEDESTRIAN_STANDOFF_S` in front of the still
        standing ego (module docstring); returns them."""
        t = session.time_s
        front: set[str] = set()
        if ego[3] < EGO_STANDING_MPS and self.held_pedestrians:
            held = _only(pedestrians, self.held_pedestrians)
            if len(held.ids):
                x, y, heading, _, length, width = ego
                radii = np.full(len(held.ids), PEDESTRIAN_RADIUS_M)
                front = {str(p) for p in held.ids[in_front(x, y, heading, length, width, held.x, held.y, radii)]}
        self.held_in_front = {pid: self.held_in_front.get(pid, t) for pid in front}
        removals = _go_round(session, self.held_in_front, PEDESTRIAN_STANDOFF_S, session.person_lane)
        self.held_pedestrians -= {r.participant for r in removals}
        return removals


def _go_round(session: SumoSession, held_since: dict[str, float], standoff_s: float,
              lane_of: Callable[[str], str]) -> list[Removal]:
    """Takes out of ``session`` (and of ``held_since``: id -> held since [s, SUMO time]) those held
    ``standoff_s`` or longer, each with the lane ``lane_of`` it stood on; returns them."""
    t = session.time_s
    removals = []
    for pid, since in list(held_since.items()):
        if t - since >= standoff_s - 1e-9:
            removals.append(Removal(t, pid, t - since, lane_of(pid)))
            session.remove(pid)
            del held_since[pid]
    return removals


def following(ego: tuple[float, float, float, float, float, float], x: FloatArray, y: FloatArray,
              heading: FloatArray) -> np.ndarray:
    """(n,) bool: which cars (centres, headings [rad]) follow the ego: within
    :data:`SWEEP_NEAR_M` of its centre, behind it, heading less than a right angle off its heading."""
    ego_x, ego_y, ego_heading = ego[:3]
    dx, dy = np.asarray(x) - ego_x, np.asarray(y) - ego_y
    behind = dx * math.cos(ego_heading) + dy * math.sin(ego_heading) < 0.0
    return behind & (np.cos(np.asarray(heading) - ego_heading) > 0.0) & (np.hypot(dx, dy) < SWEEP_NEAR_M)


def driving_into_side(ego_x: float, ego_y: float, ego_heading: float, ego_length: float, ego_width: float,
                      x: FloatArray, y: FloatArray, heading: FloatArray, speed: FloatArray,
                      length: FloatArray, width: FloatArray) -> np.ndarray:
    """:func:`driving_into` a moving ego's sides or rear only, its front
    :data:`SIDE_FRONT_EXCLUDED_M` left out (a car there is in the ego's way, the ego's to stop for)."""
    return _cars_into(ego_x, ego_y, ego_heading, ego_length, ego_width, x, y, heading, speed, length, width,
                      ego_length / 2.0 - SIDE_FRONT_EXCLUDED_M)


def watched_while_moving(cars: Cars, ego: tuple[float, float, float, float, float, float]) -> set[str]:
    """The cars the courtesy looks at while the ego moves, beside those it holds: those
    :func:`following` it and those about to drive into its side or rear (:func:`driving_into_side`)."""
    if not len(cars.ids):
        return set()
    behind = {str(i) for i in cars.ids[following(ego, cars.x, cars.y, cars.heading)]}
    return behind | _who(cars, ego, driving_into_side, NEAR_CAR_M)


def _who(movers: Movers | Cars, ego: tuple[float, float, float, float, float, float],
         test: Callable[..., np.ndarray], near_m: float = NEAR_M) -> set[str]:
    """Who among ``movers`` within ``near_m`` of the ego's centre would move into it: ``test``
    (:func:`walking_into`, :func:`riding_into`, :func:`driving_into`) on their columns."""
    ego_x, ego_y, ego_heading, _, length, width = ego
    if not len(movers.ids):
        return set()
    near = (np.hypot(np.asarray(movers.x) - ego_x, np.asarray(movers.y) - ego_y) < near_m).nonzero()[0]
    if not len(near):
        return set()
    into = test(ego_x, ego_y, ego_heading, length, width, *(np.asarray(c)[near] for c in movers[1:]))
    return {str(movers.ids[r]) for r in near[into]}


def _sweeping(cars: Cars, ways: Mapping[str, WayAhead],
              ego: tuple[float, float, float, float, float, float], only: set[str] | None) -> set[str]:
    """Who among ``cars`` with a way in ``ways`` (and in ``only``, unless None) would sweep into
    the ego along it (:func:`sweeping_into`)."""
    ego_x, ego_y, ego_heading, _, length, width = ego
    found = set()
    for r, pid in enumerate(map(str, cars.ids.tolist())):
        way = ways.get(pid)
        if way is None or (only is not None and pid not in only):
            continue
        if sweeping_into(ego_x, ego_y, ego_heading, length, width, way.points, float(cars.length[r]),
                         float(cars.width[r]), float(car_reach(cars.speed[r])), start_m=way.start_m,
                         cum=way.cum):
            found.add(pid)
    return found


def _only(movers: MoversT, ids: set[str]) -> MoversT:
    """The rows of ``movers`` whose ids are in ``ids``."""
    if not ids or not len(movers.ids):
        return type(movers)(*(np.asarray(c)[:0] for c in movers))
    rows = np.isin(movers.ids.astype(str), list(ids)).nonzero()[0]
    return type(movers)(*(np.asarray(c)[rows] for c in movers))


def _apply_holds(session: SumoSession, now: set[str], held: set[str], present_ids: np.ndarray) -> set[str]:
    """:func:`_apply` to vehicles, held and released in ``session`` as this rule (:data:`HOLDER`)."""
    return _apply(now, held, present_ids, lambda vid: session.hold_vehicle(vid, HOLDER),
                  lambda vid: session.release_vehicle(vid, HOLDER))


def _apply(now: set[str], held: set[str], present_ids: np.ndarray,
           hold: Callable[[str], None], release: Callable[[str], None]) -> set[str]:
    """Hold the new ones, release those no longer to hold that are still there; the new held set."""
    for pid in now - held:
        hold(pid)
    gone = held - now
    if gone:
        present = {str(i) for i in present_ids}
        for pid in gone & present:  # one that has left the simulation needs no release
            release(pid)
    return now
