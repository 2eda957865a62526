"""IntersectionSpec: a signalized intersection as a user writes it (YAML), validated by pydantic.

An intersection is one junction ("C", at the origin of SUMO's frame) with 3 to 5 legs. Each leg
has an entrance edge (towards the junction) and an exit edge (away from it). The geometry is
given by compass bearings, so skewed and irregular junctions are one number away from regular
ones. :mod:`crossroads.intersections.build` turns a spec into a SUMO network.

Conventions
-----------
* Bearings [deg] are compass bearings from the junction centre out along a leg: 0 = north,
  90 = east (clockwise). SUMO's frame is x east, y north [m].
* Lanes are counted from the right (SUMO's convention), car lanes only: sidewalk and bike lane
  are added by SUMO to the right of them.
* Turns are classified from the bearings alone (see :func:`relative_turn_deg`) in the same way
  SUMO classifies its connections, so the ``dir`` SUMO writes agrees with the spec; the build
  checks it.
* Right-hand traffic.

The ego vehicle always departs from the *ego approach*: the leg whose bearing is nearest 180°
(south), see SPEC §1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from crossroads.constants import ALL_RED_S, CROSS_GREEN_S, GREEN_S, YELLOW_S
from crossroads.validation import FieldProblem

TaskTurn = Literal["left", "straight", "right"]
TURN_ORDER: dict[str, int] = {"right": 0, "straight": 1, "left": 2}  # rightmost turn first

# A leg whose direction deviates less than this from straight ahead is the "straight" target.
# SUMO calls a connection straight below 44° (NBNode::getDirection); we stay a bit inside that.
STRAIGHT_TOLERANCE_DEG = 40.0
MIN_LEG_SEPARATION_DEG = 20.0  # [deg] two legs closer than this would overlap
OPPOSITE_TOLERANCE_DEG = 45.0  # [deg] a leg this close to the ego's bearing + 180° shares its phase

LegName = Annotated[str, Field(pattern=r"^[a-z][a-z0-9_]*$", max_length=32)]


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class EntranceLane(_Frozen):
    """One car lane of an entrance edge."""

    turns: tuple[TaskTurn, ...] = Field(
        min_length=1,
        description="Turns allowed from this lane, among left/straight/right (no U-turns).",
    )

    @field_validator("turns")
    @classmethod
    def _unique_turns(cls, turns: tuple[str, ...]) -> tuple[str, ...]:
        if len(set(turns)) != len(turns):
            raise ValueError(f"a turn is listed twice: {list(turns)}")
        return turns


class ApproachSpec(_Frozen):
    """One leg of the junction: an entrance edge towards the centre and an exit edge away from it."""

    name: LegName = Field(description="Leg name, a SUMO id part, e.g. 'south'. Edges: <name>_in, <name>_out.")
    bearing_deg: float = Field(
        ge=0.0, lt=360.0,
        description="[deg] compass bearing from the junction centre out along the leg (0 north, 90 east).",
    )
    entrance_lanes: tuple[EntranceLane, ...] = Field(
        min_length=1, max_length=6, description="Car lanes towards the junction, rightmost first."
    )
    exit_lanes: int = Field(ge=1, le=6, description="[-] number of car lanes leaving the junction.")
    lane_width_m: float = Field(default=3.5, ge=2.5, le=5.0, description="[m] width of every car lane.")
    length_m: float = Field(
        default=120.0, ge=40.0, le=1000.0,
        description="[m] length of the leg from the junction centre to its far end.",
    )
    median_width_m: float = Field(
        default=0.0, ge=0.0, le=20.0,
        description="[m] green belt between the entrance and exit edges; 0 = none.",
    )
    sidewalk_width_m: float = Field(
        default=2.0, ge=0.0, le=6.0, description="[m] sidewalk on both edges of the leg; 0 = none."
    )
    crossing: bool = Field(default=True, description="Pedestrian crossing over this leg (needs sidewalks).")
    bike_lane_width_m: float = Field(
        default=0.0, ge=0.0, le=3.0,
        description="[m] bike lane on both edges; 0 = bicycles share the rightmost car lane.",
    )
    speed_limit_kmh: float = Field(default=50.0, gt=0.0, le=130.0, description="[km/h] SUMO lane speed.")
    lateral_offset_m: float = Field(
        default=0.0, ge=-30.0, le=30.0,
        description=(
            "[m] shift of the leg's centre line perpendicular to its bearing, positive to the right "
            "when looking out from the centre (towards the exit edge's side); for irregular junctions."
        ),
    )

    @model_validator(mode="after")
    def _check(self) -> ApproachSpec:
        if self.crossing and self.sidewalk_width_m <= 0.0:
            raise FieldProblem("crossing", "a pedestrian crossing needs sidewalks (sidewalk_width_m > 0)")
        if 0.0 < self.sidewalk_width_m < 1.0:
            raise FieldProblem("sidewalk_width_m", "use 0 (none) or at least 1 m")
        if 0.0 < self.bike_lane_width_m < 1.0:
            raise FieldProblem("bike_lane_width_m", "use 0 (shared lane) or at least 1 m")
        return self

    @property
    def speed_limit_mps(self) -> float:
        """[m/s] the SUMO lane speed."""
        return self.speed_limit_kmh / 3.6

    @property
    def in_edge(self) -> str:
        return f"{self.name}_in"

    @property
    def out_edge(self) -> str:
        return f"{self.name}_out"

    def turns(self) -> set[str]:
        """Every turn some entrance lane of the leg allows."""
        return {t for lane in self.entrance_lanes for t in lane.turns}


class PhaseSpec(_Frozen):
    """One phase of the static signal program: a green interval followed by its yellow."""

    green_legs: tuple[LegName, ...] = Field(min_length=1, description="Legs whose straight and left links get green.")
    green_s: float = Field(gt=0.0, le=300.0, description="[s] green duration.")
    yellow_s: float = Field(default=YELLOW_S, ge=0.0, le=10.0, description="[s] yellow duration after the green.")

    @field_validator("green_legs")
    @classmethod
    def _unique_legs(cls, legs: tuple[str, ...]) -> tuple[str, ...]:
        if len(set(legs)) != len(legs):
            raise ValueError(f"a leg is listed twice: {list(legs)}")
        return legs


@dataclass(frozen=True)
class LaneLink:
    """A planned car connection: car-lane indices counted from the right, without sidewalk/bike lane."""

    from_leg: str
    from_lane: int
    to_leg: str
    to_lane: int
    turn: str


class IntersectionSpec(_Frozen):
    """A signalized intersection: legs, lanes, and its static signal program (SPEC §1-2)."""

    name: str = Field(pattern=r"^[a-z0-9][a-z0-9_\-]*$", max_length=64, description="Identifier, used in file names.")
    description: str = Field(default="", description="Free text: what the intersection stands for.")
    approaches: tuple[ApproachSpec, ...] = Field(min_length=3, max_length=5, description="The legs, any order.")
    phases: tuple[PhaseSpec, ...] | None = Field(
        default=None,
        description=(
            "Signal phases in order; None = SPEC §2 default: the ego's axis G60/Y3, then the other legs "
            "G37/Y3 (the ego's approach sees G60/Y3/R40)."
        ),
    )
    kerb_radius_m: float | None = Field(
        default=None, ge=1.0, le=30.0,
        description=(
            "[m] radius of the kerbs rounding the junction's corners (netconvert's node radius): "
            "the larger, the further back the stop lines and the gentler the turns; None = "
            "netconvert's own choice."
        ),
    )
    expected_candidates: dict[TaskTurn, Annotated[int, Field(ge=0)]] | None = Field(
        default=None,
        description="[-] documentation: candidate paths per task for the ego's approach; checked against the lanes.",
    )

    # ---- validation ---------------------------------------------------------------------------
    @model_validator(mode="after")
    def _check(self) -> IntersectionSpec:
        names = [a.name for a in self.approaches]
        for i, name in enumerate(names):
            if name in names[:i]:
                raise FieldProblem(f"approaches.{i}.name", f"leg name {name!r} is used twice")
        for i, a in enumerate(self.approaches):
            for j in range(i):
                gap = abs(_wrap_deg(a.bearing_deg - self.approaches[j].bearing_deg))
                if gap < MIN_LEG_SEPARATION_DEG:
                    raise FieldProblem(
                        f"approaches.{i}.bearing_deg",
                        f"leg {a.name!r} is {gap:.1f}° from leg {self.approaches[j].name!r}; "
                        f"legs must be at least {MIN_LEG_SEPARATION_DEG:.0f}° apart",
                    )
        for i, a in enumerate(self.approaches):
            self._check_lanes(i, a)
        if self.phases is not None:
            self._check_phases()
        if self.expected_candidates is not None:
            actual = self.candidate_counts()
            for turn, count in self.expected_candidates.items():
                if actual.get(turn, 0) != count:
                    raise FieldProblem(
                        f"expected_candidates.{turn}",
                        f"declares {count} but the lanes of the ego approach {self.ego_approach.name!r} "
                        f"give {actual.get(turn, 0)}",
                    )
        return self

    def _check_lanes(self, i: int, a: ApproachSpec) -> None:
        targets = self.turn_targets(a.name)
        for j, lane in enumerate(a.entrance_lanes):
            for k, turn in enumerate(lane.turns):
                if turn not in targets:
                    raise FieldProblem(
                        f"approaches.{i}.entrance_lanes.{j}.turns.{k}",
                        f"no leg lies {_turn_phrase(turn)} of leg {a.name!r}, so no exit lane is reachable",
                    )
            if j > 0:
                prev = a.entrance_lanes[j - 1]
                if max(TURN_ORDER[t] for t in prev.turns) > min(TURN_ORDER[t] for t in lane.turns):
                    raise FieldProblem(
                        f"approaches.{i}.entrance_lanes.{j}.turns",
                        f"turns {list(lane.turns)} would cross those of the lane to its right "
                        f"{list(prev.turns)}: order lanes right, straight, left from the right",
                    )

    def _check_phases(self) -> None:
        assert self.phases is not None
        names = {a.name for a in self.approaches}
        served: set[str] = set()
        for p, phase in enumerate(self.phases):
            for k, leg in enumerate(phase.green_legs):
                if leg not in names:
                    raise FieldProblem(
                        f"phases.{p}.green_legs.{k}", f"unknown leg {leg!r}; legs: {sorted(names)}"
                    )
            served.update(phase.green_legs)
        if names - served:
            raise FieldProblem("phases", f"legs never get green: {sorted(names - served)}")

    # ---- geometry of turns ------------------------------------------------------------------
    def approach(self, name: str) -> ApproachSpec:
        for a in self.approaches:
            if a.name == name:
                return a
        raise KeyError(f"{self.name}: no leg {name!r}; legs: {[a.name for a in self.approaches]}")

    @property
    def ego_approach(self) -> ApproachSpec:
        """The leg the ego departs from: bearing nearest 180° (south)."""
        return min(self.approaches, key=lambda a: abs(_wrap_deg(a.bearing_deg - 180.0)))

    def turn_targets(self, leg: str) -> dict[str, str]:
        """``{turn: target leg}`` for the turns physically possible from ``leg``'s entrance.

        Straight: the leg nearest straight ahead, if within :data:`STRAIGHT_TOLERANCE_DEG`. Right:
        the remaining leg furthest to the right (the first one clockwise... in compass terms, the
        neighbour on the right); left: the remaining one furthest to the left. Middle legs of a
        5-leg junction are not reached. This matches SUMO's 's'/'r'/'l' classification.
        """
        src = self.approach(leg)
        others = [(relative_turn_deg(src.bearing_deg, a.bearing_deg), a.name) for a in self.approaches if a.name != leg]
        targets: dict[str, str] = {}
        ahead = min(others, key=lambda o: abs(o[0]))
        if abs(ahead[0]) < STRAIGHT_TOLERANCE_DEG:
            targets["straight"] = ahead[1]
            others.remove(ahead)
        rights = [o for o in others if o[0] > 0.0]
        lefts = [o for o in others if o[0] < 0.0]
        if rights:
            targets["right"] = max(rights)[1]
        if lefts:
            targets["left"] = min(lefts)[1]
        return targets

    def lane_links(self) -> list[LaneLink]:
        """Every car connection of the junction, planned lane to lane.

        For a turn allowed by ``n`` lanes into a target leg with ``m`` exit lanes, the lanes split
        the exit lanes in order without crossing: with ``n <= m`` lane ``k`` (k-th from the right
        among those lanes) reaches exit lanes ``[k*m//n, (k+1)*m//n)``, so a single lane reaches
        all ``m`` (the paper's one candidate per target lane); with ``n > m`` lane ``k`` reaches
        exit lane ``k*m//n``. Every exit lane of the target is therefore reachable.
        """
        links: list[LaneLink] = []
        for a in self.approaches:
            targets = self.turn_targets(a.name)
            for turn in ("right", "straight", "left"):
                lanes = [j for j, lane in enumerate(a.entrance_lanes) if turn in lane.turns]
                if not lanes:
                    continue
                target = self.approach(targets[turn])
                n, m = len(lanes), target.exit_lanes
                for k, lane in enumerate(lanes):
                    exits = range(k * m // n, (k + 1) * m // n) if n <= m else [k * m // n]
                    links.extend(LaneLink(a.name, lane, target.name, e, turn) for e in exits)
        return links

    def candidate_counts(self, leg: str | None = None) -> dict[str, int]:
        """[-] candidate paths per task from ``leg`` (default: the ego's): distinct reachable exit lanes."""
        leg = leg or self.ego_approach.name
        counts: dict[str, set[tuple[str, int]]] = {}
        for link in self.lane_links():
            if link.from_leg == leg:
                counts.setdefault(link.turn, set()).add((link.to_leg, link.to_lane))
        return {turn: len(v) for turn, v in counts.items()}

    # ---- signals -----------------------------------------------------------------------------
    @property
    def signal_phases(self) -> tuple[PhaseSpec, ...]:
        """The phases to build: the given ones, or the SPEC §2 default two-phase program."""
        if self.phases is not None:
            return self.phases
        ego = self.ego_approach
        axis = [ego.name]
        others = [a for a in self.approaches if a is not ego]
        opposite = min(others, key=lambda a: abs(_wrap_deg(a.bearing_deg - ego.bearing_deg - 180.0)))
        if abs(_wrap_deg(opposite.bearing_deg - ego.bearing_deg - 180.0)) <= OPPOSITE_TOLERANCE_DEG:
            axis.append(opposite.name)
        cross = tuple(a.name for a in self.approaches if a.name not in axis)
        return (
            PhaseSpec(green_legs=tuple(axis), green_s=GREEN_S, yellow_s=YELLOW_S),
            PhaseSpec(green_legs=cross, green_s=CROSS_GREEN_S, yellow_s=YELLOW_S),
        )

    @property
    def cycle_s(self) -> float:
        """[s] duration of one signal cycle."""
        return sum(p.green_s + p.yellow_s + ALL_RED_S for p in self.signal_phases)


def relative_turn_deg(from_bearing_deg: float, to_bearing_deg: float) -> float:
    """[deg] turn from driving in along leg ``from`` to driving out along leg ``to``, in (-180, 180].

    Positive = clockwise = to the right; 0 = straight on; ±180 = U-turn. The direction of travel
    into the junction is the reverse of the entrance leg's bearing.
    """
    return _wrap_deg(to_bearing_deg - (from_bearing_deg + 180.0))


def _wrap_deg(angle_deg: float) -> float:
    """Wrap an angle into (-180, 180] degrees."""
    wrapped = math.fmod(angle_deg, 360.0)
    if wrapped <= -180.0:
        wrapped += 360.0
    elif wrapped > 180.0:
        wrapped -= 360.0
    return wrapped


def _turn_phrase(turn: str) -> str:
    return {"straight": f"within {STRAIGHT_TOLERANCE_DEG:.0f}° of straight ahead", "left": "to the left",
            "right": "to the right"}[turn]
