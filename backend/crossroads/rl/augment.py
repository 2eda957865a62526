"""Synthetic training states: a car standing on the ego's path ahead of it (a **(choice)**).

Why (docs/tried/training.md): the models' collisions are mostly with a vehicle
that stands in front of the ego, in the pass mode — the vehicle ahead has stood less than the 3 s
after which the light logic switches to the stop mode. The sampler sees such states only for those
few seconds of each queue, and ``benchmarks/research/queue_response.py`` showed the shipped policies driving
into a single car standing on an empty road from almost every speed and gap (APG 22, DPG 24 of 24). So a share of the sampled states also enters the
buffer as a copy with one more participant: a car (SUMO's passenger car, 5.0 × 1.8 m) standing on
the candidate path the state is recorded with, a gap drawn uniformly ahead of the ego — beyond
the distance full braking needs from the ego's speed and acceleration (``stoppable``),
or bumper to bumper. The differentiable model then scores every plan from that copy
against the standing car; nothing else of the state changes (the speed mode included, as the light
logic would keep it for 3 s).

Why beyond the braking distance: from 8 m/s full braking needs 14 m, so a bumper gap drawn in
0.5–30 m made almost half of those copies collisions no plan avoids, where the least-bad plan
swerves; a run trained on them stopped for the queue test's car only from 2–4 m/s and
tracked its straight paths worse. A copy that can be stopped for teaches braking alone.

The car takes the farthest vehicle slot (a padded one when there is one) and the vehicle slots are
sorted again by distance to the ego, as ``idc.state.select_others`` orders them. Pure numpy.

Neighbours (``standing_car_neighbours``): a real queue is not one car on an empty road.
A model trained on stoppable copies stopped for the queue test's lone car from every speed, yet with the scene's other vehicles
in the slots its plan still met the car ahead in 22 of 29 pre-collision states (3 of 29 with the
other slots padded: docs/tried/training.md). So a copy may also get standing
cars where a queue has them: one more behind the car ahead in the ego's own lane, and cars in the
neighbouring lanes (a lane width to the left or right of the path, along it from beside the ego to
past the car ahead). None of them is on the path, so the plan that brakes for the car ahead stays
the right one; they only make the car ahead one of several standing cars in the slots.
"""

from __future__ import annotations

import numpy as np

from crossroads.constants import EGO_LENGTH_M
from crossroads.idc.constraints import LANE_WIDTH_M  # neighbours stand one lane width off the path
from crossroads.idc.state import ACC, KIND_ROWS, O_PX, O_PY, PX, PY, VX
from crossroads.planning.routes import CandidatePath
from crossroads.rl.buffer import Samples
from crossroads.sim.ego import braking_distance_m

CAR_LENGTH_M = 5.0  # [m] SUMO's default passenger car
CAR_WIDTH_M = 1.8  # [m]
QUEUE_SPACING_M = (1.0, 3.0)  # [m] bumper gap between queued cars, drawn uniformly
BESIDE_FROM_M = -8.0  # [m] a neighbour stands from this far behind the ego's centre...
BESIDE_PAST_M = 10.0  # [m] ...to this far past the car ahead, along the path


def _stand_on(block: np.ndarray, block_kappa: np.ndarray, slot: int, x: float, y: float, heading: float) -> None:
    block[slot] = (x, y, 0.0, heading, CAR_LENGTH_M, CAR_WIDTH_M)
    block_kappa[slot] = 0.0


def with_standing_car(sample: Samples, row: int, path: CandidatePath, gap_m: float,
                      neighbours: tuple[tuple[float, float], ...] = ()) -> Samples:
    """Row ``row`` of ``sample`` as a one-row sample with a car standing ``gap_m`` (bumper to bumper)
    ahead of the ego on ``path``, its curvature 0. Beyond the path's end the car stands at the end.

    ``neighbours``: more standing cars, each (arc length past the ego's centre [m], lateral offset
    from the path [m], + left); they take the next farthest vehicle slots."""
    ego = sample.ego[row]
    here = path.project(float(ego[PX]), float(ego[PY]))
    others = sample.others[row].copy()
    kappa = sample.kappa[row].copy()
    vehicles = KIND_ROWS["vehicle"]
    block, block_kappa = others[vehicles], kappa[vehicles]
    x, y, heading, _ = path.reference_at(here.s_m + gap_m + 0.5 * (EGO_LENGTH_M + CAR_LENGTH_M))
    _stand_on(block, block_kappa, -1, x, y, heading)
    for k, (along_m, across_m) in enumerate(neighbours[: len(block) - 1]):
        x, y, heading, _ = path.reference_at(here.s_m + along_m)
        _stand_on(block, block_kappa, -2 - k, x - across_m * np.sin(heading), y + across_m * np.cos(heading), heading)
    order = np.argsort(np.hypot(block[:, O_PX] - ego[PX], block[:, O_PY] - ego[PY]), kind="stable")
    others[vehicles], kappa[vehicles] = block[order], block_kappa[order]
    return Samples(sample.ego[row:row + 1].copy(), others[None], kappa[None],
                   sample.path[row:row + 1].copy(), sample.stop[row:row + 1].copy())


def queue_neighbours(gap_m: float, count: int, rng: np.random.Generator) -> tuple[tuple[float, float], ...]:
    """``count`` standing cars around a car ``gap_m`` ahead (bumper to bumper) of the ego, as
    (along [m] past the ego's centre, across [m]): the first queues behind that car in the ego's
    lane, the rest stand in the lane left or right of the path anywhere from beside the ego to past
    the car ahead."""
    out: list[tuple[float, float]] = []
    ahead_centre = gap_m + 0.5 * (EGO_LENGTH_M + CAR_LENGTH_M)
    for k in range(count):
        if k == 0:
            out.append((ahead_centre + CAR_LENGTH_M + float(rng.uniform(*QUEUE_SPACING_M)), 0.0))
        else:
            side = LANE_WIDTH_M if rng.random() < 0.5 else -LANE_WIDTH_M
            out.append((float(rng.uniform(BESIDE_FROM_M, ahead_centre + BESIDE_PAST_M)), side))
    return tuple(out)


def standing_car_copies(samples: Samples, path: CandidatePath, share: float, gap_range_m: tuple[float, float],
                        rng: np.random.Generator, stoppable: bool = False, neighbours: int = 0) -> Samples:
    """Copies of a ``share`` of ``samples`` (all recorded on ``path``), each with a standing car ahead:
    a gap drawn from ``gap_range_m``, bumper to bumper, or with ``stoppable`` beyond the ego's braking
    distance (so the same draws place the car farther ahead). ``neighbours`` > 0: each copy also
    gets 0..``neighbours`` more standing cars (drawn uniformly, :func:`queue_neighbours`); 0 draws
    nothing more, so the copies are those of runs before the option."""
    if share <= 0.0 or len(samples.ego) == 0:
        return Samples.empty()
    chosen = np.flatnonzero(rng.random(len(samples.ego)) < share)
    gaps = rng.uniform(*gap_range_m, size=len(chosen))
    if stoppable and len(chosen):
        ego = samples.ego[chosen]
        gaps = gaps + braking_distance_m(ego[:, VX], ego[:, ACC])
    around = [queue_neighbours(float(g), int(rng.integers(0, neighbours + 1)), rng) if neighbours else ()
              for g in gaps]
    return Samples.concat([with_standing_car(samples, int(i), path, float(g), n)
                           for i, g, n in zip(chosen, gaps, around)])
