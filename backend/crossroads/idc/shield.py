"""A safety shield for the online decision: keep a way to brake clear of everyone.

**(choice)** Not in the paper, and off unless asked for (a policy reference ending in ``+shield``,
``crossroads.policy.ref``): the bare policy is what APG and DPG are compared by.

Why: 2 s before the collisions of the trained models on the nominal left turn, the training model
itself (rl.idc_model: f_ego, f_other with each participant's route curvature, ξ ≡ 0) already predicted
the policy's plan to run into the other participant — the bodies' circles met within the T = 25
steps in 24 of 37 collisions of one trained APG, while full braking kept J_safe under 1 in 27 of
them (docs/tried/shield.md). The policy does not act on a danger its model
sees; the shield does.

The check, every step, after the value network has chosen τ* and the policy its action u: the
participants the sensors cover are predicted with f_other (each turning by its route's curvature, as
the training model predicts them) over ``SHIELD_HORIZON_STEPS``, long enough for full braking from the
pass-mode speed to stand still, in two futures: each keeping its speed, and each braking hard to a
stand (a follower — behind the ego, heading its way — brakes in both, :func:`followers`). The ego
is rolled out with f_ego along two backups —

* *go*: u now, then full braking (Δa = −4.5 m/s³ each step);
* *brake*: full braking from now;

both with the wheel held (Δδ = 0), or, within 15° of the path's exit heading, turned back toward
straight (:func:`braking_action`). When the shield brakes, its command is *brake*'s first action,
the wheel included: what it drives is then the backup it checked, and what the last step's *go*
checked after u.

If *go* keeps the ego's circles ``SHIELD_CLEARANCE_M`` (the training constraints' safety margin)
apart from every participant's in both futures of :func:`predicted_others`, u is the command: after
it the ego can still stop clear. If not, the backups are compared participant by participant
(:func:`go_is_worse`): where *go* intrudes deeper on someone and *brake* on no one, the command is
braking's first action; where braking helps no one, u stands (standing 2.8 m from a car in a narrow
neighbouring lane, both intrude as deep); where each is worse for someone (a participant closing
from the side), the shallower deepest intrusion decides — except at a held stop line and short of
the stop line, where braking wins.

While the light holds the ego at the stop line (red, or yellow in the stop mode:
:func:`crossroads.idc.lights.light_holds_at_line`), the line is a standing obstacle too: a backup
that ends less than ``STOP_LINE_GAP_M`` short of it intrudes by the shortfall (:func:`travelled_m`),
and the larger of the two intrusions counts. Without it the shipped APG, which tracks the stop
profile loosely, crossed a red line on an empty road at 4.7 m/s; with it APG and DPG stand 0.50 m
short (docs/tried/shield.md). A pedestrian crossing that someone is on in the ego's
path is such a line too, while full braking can still stand short of it (the decision passes the
nearer of the two: :mod:`crossroads.idc.crosswalks`).

What was measured against it, on 60 seeds of the nominal left turn that are not the evaluation's
(base seed 777) with an earlier APG — passed / collisions / timeouts: this rule 16 / 27 / 16; counting
only what the backups add to the intrusions of the present 11 / 38 / 10; braking whenever *brake*
enters the clearance no sooner than *go* 10 / 35 / 13; ranking by the exterior penalty Σ max(0, g)²
along each backup 12 / 27 / 19; no shield 8 / 52 / 0; the rule-based controller 24 / 3 / 33. Where
neither backup can stop any more, both drive through the other body in the prediction and the
deepest intrusions say little (the shield may then keep the policy's action); the shield is for
not getting there.

Checking the go-then-brake backup, not the policy's own plan over the next 2.5 s, matters: measured
on the first 20 seeds of the nominal left turn with an earlier APG, a shield that braked only once the
plan's circles met within 25 steps stepped in too late, and in 3 of them the ego (6.8–8.4 m/s five
seconds before) still hit a standing car while braking. Pure numpy, vectorised over time for the
participants (their prediction does not depend on the ego), so a check costs ~0.4 ms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from crossroads.constants import DT_S, JERK_MAX, OTHER_DECEL_MPS2, STEER_RATE_MAX, STOP_LINE_GAP_M
from crossroads.geometry import wrap_scalar
from crossroads.idc.constraints import SAFETY_MARGIN_M, circle_gap, ego_circles, participant_circles
from crossroads.idc.state import DELTA, KIND_ROWS, N_OTHERS, O_L, O_PHI, O_PX, O_PY, O_V, PHI, PX, PY
from crossroads.sim.ego import ego_step_floats

# [m] the clearance the backups must keep between circles: the training constraints' safety margin.
# With none (the bodies' circles only) the ego braked from 3.6 m/s at the last moment the model
# allowed and touched the standing car at 1.6 m/s (f_ego against SUMO's moves, noisy lengths)
SHIELD_CLEARANCE_M = SAFETY_MARGIN_M
SHIELD_HORIZON_STEPS = 40  # [0.1 s] full braking stops from 8.33 m/s within ~36 steps (f_ego, jerk-limited)
FOLLOWER_HEADING_RAD = np.pi / 4  # [rad] a participant behind heading within this of the ego follows it
PEDESTRIAN_SLOTS = np.arange(N_OTHERS) >= KIND_ROWS["pedestrian"].start
_GO, _BRAKE = 0, 1  # the rows of the backups
_LINE = -1  # the stop line's column in Backups.by_obstacle, after the participant slots


@dataclass(frozen=True)
class ShieldVerdict:
    """What the shield made of one step's action."""

    action: np.ndarray  # (2,) the command: the policy's, or braking's first action
    braking: bool  # the shield replaced the policy's action
    backups: Backups  # what the decision was made from


def predicted_others(others: np.ndarray, kappa: np.ndarray, steps: int) -> np.ndarray:
    """The participants ``others`` (16, 6) with curvatures ``kappa`` (16,) over ``steps``: (2, steps,
    16, 6), [0] f_other with ξ ≡ 0 (each keeps its speed), [1] the same with ξ_v braking each at
    ``OTHER_DECEL_MPS2`` to a stand; row i after i + 1 steps. f_other's recursion (p moves with the
    old v and φ, φ turns with the old v) summed in closed form over the steps at once: the same
    numbers as stepping ``sim.other.other_step`` (tests), without a Python loop."""
    o = np.asarray(others, np.float64)
    k = np.asarray(kappa, np.float64)
    v = np.empty((2, steps + 1, len(o)))  # [future, before step i, participant]
    v[0] = o[:, O_V]
    v[1] = np.maximum(o[:, O_V] - np.arange(steps + 1)[:, None] * (OTHER_DECEL_MPS2 * DT_S), 0.0)
    step_m = DT_S * v[:, :-1]  # both futures at once, each value computed as one future alone computes it
    travelled = np.zeros_like(v)  # before step i
    np.cumsum(step_m, axis=1, out=travelled[:, 1:])
    phi = o[:, O_PHI] + travelled * k  # (2, steps + 1, 16)
    out = np.empty((2, steps) + o.shape)
    out[..., O_PX] = o[:, O_PX] + np.cumsum(step_m * np.cos(phi[:, :-1]), axis=1)
    out[..., O_PY] = o[:, O_PY] + np.cumsum(step_m * np.sin(phi[:, :-1]), axis=1)
    out[..., O_V] = v[:, 1:]
    out[..., O_PHI] = phi[:, 1:]
    out[..., O_L:] = o[:, O_L:]
    return out


def followers(ego: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Which of ``others`` (16, 6) follow the ego (16,) bool: vehicles and cyclists behind its centre
    heading its way within ``FOLLOWER_HEADING_RAD``. Kept at their speed, a follower 25 m back at
    8 m/s drives into the braking ego in the prediction, and every backup looks as bad as the plan:
    on the nominal left turn that hid the standing car ahead until the ego hit it. A follower is
    predicted braking instead, as SUMO's car-following brakes for the ego."""
    o = np.asarray(others, np.float64)
    c, s = np.cos(ego[PHI]), np.sin(ego[PHI])
    along = c * (o[:, O_PX] - ego[PX]) + s * (o[:, O_PY] - ego[PY])
    same_way = np.cos(o[:, O_PHI] - ego[PHI]) > np.cos(FOLLOWER_HEADING_RAD)
    return (along < 0.0) & same_way & ~PEDESTRIAN_SLOTS


class Backups(NamedTuple):
    """How the two backups fare against the predicted participants and the stop line (module
    docstring); an intrusion > 0 says the backup enters the clearance, or passes the line's gap."""

    # (2, 17) the deepest intrusion per obstacle [m], [0] along *go*, [1] along *brake*: the 16
    # participant slots, then the line (−inf when no line holds the ego)
    by_obstacle: np.ndarray

    @property
    def go_overlap_m(self) -> float:
        """Deepest intrusion along *go* [m], over every obstacle."""
        return float(self.by_obstacle[_GO].max())

    @property
    def brake_overlap_m(self) -> float:
        """The same along *brake*."""
        return float(self.by_obstacle[_BRAKE].max())

    @property
    def go_past_line_m(self) -> float:
        """How far *go* ends past the point STOP_LINE_GAP_M short of the line (−inf: no line)."""
        return float(self.by_obstacle[_GO, _LINE])

    @property
    def brake_past_line_m(self) -> float:
        """The same along *brake*."""
        return float(self.by_obstacle[_BRAKE, _LINE])


# [Δδ rad/s, Δa m/s³] the shield's braking step (:func:`braking_action`) until the end of the turn, in
# its command and in both backups alike: full braking, the wheel held. Why the command too: the
# backups are checked with the wheel held, and a braking step that kept the policy's steering rate
# drove another path than the one checked. On the nominal left turn the trained policy swerves left
# around a queued car; *go*, curving left on the held wheel, cleared the car, the ego braked while
# the policy steered back right, and it hit the car it had been predicted to pass (27 of the 57
# collisions of 200 runs, 150 s timeout: the ego 4.0–4.8 m behind a standing car, centres, and
# 0.2–2.2 m to its left; seeds 352480436, 1284190969, docs/tried/shield.md)
HOLD_WHEEL = np.array([0.0, -JERK_MAX])
HOLD_WHEEL.flags.writeable = False  # shared by every braking step: a caller that wants to change it copies
# [rad] within this of its path's exit heading the ego is at the end of its turn: braking there turns
# the wheel back toward straight (at the steering-rate limit) instead of holding it. Why: held at the
# end of the left turn, the wheel swung the nose into the opposite leg's cars at their stop line
# (6 of 9 such collisions at 150 s were seeds that had passed before the wheel was held), while
# straightened mid-turn it took the ego off its arc into a cyclist (seed 514166452)
EXIT_ALIGNED_RAD = math.radians(15.0)


def braking_action(ego: np.ndarray, exit_heading: float | None = None) -> np.ndarray:
    """The shield's braking step from ``ego`` (8,): full braking, the wheel held (``HOLD_WHEEL``, read
    only), or turned back toward straight once the ego heads within ``EXIT_ALIGNED_RAD`` of
    ``exit_heading``."""
    if _holds_wheel(float(ego[PHI]), exit_heading):
        return HOLD_WHEEL
    return np.array([_straightening_rate(float(ego[DELTA])), -JERK_MAX])


def _holds_wheel(phi: float, exit_heading: float | None) -> bool:
    """Whether braking at heading ``phi`` holds the wheel (:func:`braking_action`)."""
    return exit_heading is None or abs(wrap_scalar(phi - exit_heading)) >= EXIT_ALIGNED_RAD


def _straightening_rate(delta: float) -> float:
    """[rad/s] the steering rate that turns the wheel from ``delta`` back toward straight."""
    return min(max(-delta / DT_S, -STEER_RATE_MAX), STEER_RATE_MAX)


def _braking_floats(phi: float, delta: float, exit_heading: float | None) -> tuple[float, float]:
    """:func:`braking_action` of an ego at heading ``phi`` with wheel angle ``delta``, as two
    Python floats (it runs for every step of both backups)."""
    return (0.0 if _holds_wheel(phi, exit_heading) else _straightening_rate(delta)), -JERK_MAX


# [m] an obstacle counts as intruded deeper along one backup than the other only past this: below
# it the two differ by rounding (one step of go from a stand moves the ego ~1 mm)
SHIELD_TIE_M = 1e-4
# [m] once the shield has braked, *go* must keep this much more than the clearance before the policy
# gets its action back. Why: perceived positions jitter (σ 0.15 m); standing up to 0.47 m inside the
# clearance of a standing car, the car's noise let *go* look clear on single steps, two such steps
# in a row built up Δa, and the ego crept into the car at 0.13 m/s (60 s nominal left, seed 1596428704).
SHIELD_RELEASE_MARGIN_M = 0.3


def go_is_worse(by_obstacle: np.ndarray, tie_m: float = SHIELD_TIE_M, before_line: bool = False,
                release_m: float = 0.0) -> bool:
    """Whether the shield brakes, from the per-obstacle intrusions ``by_obstacle`` (2, n) of
    :class:`Backups`: *go* intrudes somewhere (> 0) deeper than *brake*, and *brake* nowhere deeper
    than *go*; where each is worse somewhere, the shallower deepest intrusion wins (module docstring).

    Per obstacle, not the deepest of all: compared by the deepest intrusion alone, another
    participant equally deep along both backups hid the queued car ahead, which the ego crept into
    from a stand at 0.3 m/s (150 s nominal left, seed 2124181941, docs/tried/shield.md).

    Two exceptions, where braking wins whatever the participants' intrusions say:

    * a held stop line that *go* ends deeper past. Traded against a right-turner predicted 2.1 m
      deep in both backups, it let the shipped APG run a red line (seed 393922021);
    * ``before_line``, the ego not yet past its stop line: standing short of it, the ego is in no
      one's way but its followers' (predicted braking), so a participant predicted deeper along
      *brake* there is the prediction's artefact (a turner kept on its curvature).

    ``release_m``: an obstacle counts as intruded along *go* from −release_m on (the hysteresis of
    ``SHIELD_RELEASE_MARGIN_M`` after a braking step).
    """
    go, brake = by_obstacle[_GO], by_obstacle[_BRAKE]
    if go[_LINE] > 0.0 and go[_LINE] > brake[_LINE] + tie_m:
        return True  # a held stop line is not traded against anyone: escaping forward means running the red
    go_deeper = bool(np.any((go > -release_m) & (go > brake + tie_m)))
    if not go_deeper:
        return False  # go is clear, or braking helps nobody
    if before_line:
        return True  # short of the stop line no one crossing the junction can reach a standing ego
    brake_deeper = bool(np.any((brake > 0.0) & (brake > go + tie_m)))
    return not brake_deeper or float(brake.max()) < float(go.max())


def travelled_m(start: np.ndarray, egos: np.ndarray) -> np.ndarray:
    """The distance (n,) each of the n rollouts ``egos`` (steps, n, 8) from ``start`` (8,) covers:
    the length of its polyline of centres (the paths near a stop line are straight to within mm)."""
    points = np.concatenate([np.broadcast_to(start[[PX, PY]], (1, egos.shape[1], 2)), egos[:, :, [PX, PY]]])
    return np.linalg.norm(np.diff(points, axis=0), axis=-1).sum(axis=0)


def backups(ego: np.ndarray, others: np.ndarray, kappa: np.ndarray, action: np.ndarray,
            steps: int = SHIELD_HORIZON_STEPS, line_m: float | None = None,
            exit_heading: float | None = None) -> Backups:
    """*go* and *brake* from ``ego`` (8,) with the policy's ``action`` (2,) (module docstring),
    against every participant of ``others`` (16, 6) turning by ``kappa`` (16,) in both futures and,
    when the light holds the ego at the line, ``line_m`` ahead of its front bumper."""
    ego = np.asarray(ego, np.float64)
    start = ego.tolist()
    go = np.asarray(action, np.float64).reshape(2).tolist()
    rollouts = []
    for first in (go, _braking_floats(start[PHI], start[DELTA], exit_heading)):  # _GO, _BRAKE
        state = ego_step_floats(start, *first)  # f_ego on Python floats: 80 steps a decision
        rollout = [state]
        for _ in range(steps - 1):
            state = ego_step_floats(state, *_braking_floats(state[PHI], state[DELTA], exit_heading))
            rollout.append(state)
        rollouts.append(rollout)
    egos = np.ascontiguousarray(np.array(rollouts, dtype=np.float64).reshape(2, steps, 8).transpose(1, 0, 2))
    by_slot = _deepest_by_slot(ego, egos, np.asarray(others, np.float64), np.asarray(kappa, np.float64), steps)
    past = (np.full(2, -np.inf) if line_m is None
            else travelled_m(ego, egos) - (line_m - STOP_LINE_GAP_M))  # (2,)
    return Backups(np.concatenate([by_slot, past[:, None]], axis=1))


def _deepest_by_slot(ego: np.ndarray, egos: np.ndarray, others: np.ndarray, kappa: np.ndarray, steps: int) -> np.ndarray:
    """(2, 16): each slot's deepest intrusion along each backup ``egos`` (steps, 2, 8), the worse of
    the futures of :func:`predicted_others` at every step."""
    moved = predicted_others(others, kappa, steps)
    follows = followers(ego, others)
    moved[0][:, follows] = moved[1][:, follows]  # a follower brakes when the ego does
    return deepest_intrusions(egos, moved)


def deepest_intrusions(egos: np.ndarray, moved: np.ndarray) -> np.ndarray:
    """(2, 16) each slot's deepest intrusion along each backup ``egos`` (steps, 2, 8) against the
    futures ``moved`` (futures, steps, 16, 6) of :func:`predicted_others`: the largest value of
    ``deepest_by_slot(safety_constraints(state, SHIELD_CLEARANCE_M))`` over the states pairing a
    backup's ego with a future's participants at each step, bit for bit (the same
    ``constraints.circle_gap`` of the same circles; a maximum does not depend on the order), without
    a state built for each pair. Laid out with every participant circle last, so numpy's loops run
    over 24 circles, not over the 2 of the ego as ``safety_constraints``' order has it."""
    ex, ey, er = ego_circles(egos)
    ex, ey = ex[None, ..., None], ey[None, ..., None]  # (1, steps, 2 backups, 2 ego circles, 1)
    two_x, two_y, r2, one_x, one_y, r1 = participant_circles(moved)  # (futures, steps, slots, circles)
    futures, steps = moved.shape[:2]
    out = []
    for cx, cy, r in ((two_x, two_y, r2), (one_x, one_y, r1)):
        slots, circles = cx.shape[-2:]
        flat = [a.reshape(futures, steps, 1, 1, slots * circles) for a in (cx, cy, np.broadcast_to(r, cx.shape))]
        g = circle_gap(*flat, ex, ey, er, SHIELD_CLEARANCE_M)  # (futures, steps, 2 backups, 2 ego circles, slots·circles)
        # over every future and step first: numpy reduces a leading axis far faster than inner ones
        out.append(g.reshape(futures * steps, 2, 2, slots, circles).max(axis=0).max(axis=(1, 3)))
    return np.concatenate(out, axis=1)


def shield_action(ego: np.ndarray, others: np.ndarray, kappa: np.ndarray, action: np.ndarray,
                  line_m: float | None = None, before_line: bool = False,
                  braked_last_step: bool = False, exit_heading: float | None = None) -> ShieldVerdict:
    """The command for a step whose policy action is ``action`` (module docstring); ``line_m`` is
    the front bumper's distance to the stop line [m] when the light holds the ego there, else None;
    ``exit_heading`` the heading [rad] the ego's path ends in (:func:`braking_action`)."""
    b = backups(ego, others, kappa, action, line_m=line_m, exit_heading=exit_heading)
    braking = go_is_worse(b.by_obstacle, before_line=before_line,
                          release_m=SHIELD_RELEASE_MARGIN_M if braked_last_step else 0.0)
    command = (braking_action(np.asarray(ego, np.float64), exit_heading) if braking else np.asarray(action, np.float64)).copy()
    return ShieldVerdict(command, braking, b)
