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

(More standing cars around the one ahead, queued behind it and in the neighbouring lanes, lost:
docs/tried/training.md, "What the adversary and the queues hid".)
"""

from __future__ import annotations

import numpy as np

from crossroads.constants import EGO_LENGTH_M
from crossroads.idc.state import ACC, KIND_ROWS, O_PX, O_PY, PX, PY, VX
from crossroads.planning.routes import CandidatePath
from crossroads.rl.buffer import Samples
from crossroads.sim.ego import braking_distance_m

CAR_LENGTH_M = 5.0  # [m] SUMO's default passenger car
CAR_WIDTH_M = 1.8  # [m]


def with_standing_car(sample: Samples, row: int, path: CandidatePath, gap_m: float) -> Samples:
    """Row ``row`` of ``sample`` as a one-row sample with a car standing ``gap_m`` (bumper to bumper)
    ahead of the ego on ``path``, its curvature 0. Beyond the path's end the car stands at the end."""
    ego = sample.ego[row]
    here = path.project(float(ego[PX]), float(ego[PY]))
    others = sample.others[row].copy()
    kappa = sample.kappa[row].copy()
    vehicles = KIND_ROWS["vehicle"]
    block, block_kappa = others[vehicles], kappa[vehicles]
    x, y, heading, _ = path.reference_at(here.s_m + gap_m + 0.5 * (EGO_LENGTH_M + CAR_LENGTH_M))
    block[-1] = (x, y, 0.0, heading, CAR_LENGTH_M, CAR_WIDTH_M)
    block_kappa[-1] = 0.0
    order = np.argsort(np.hypot(block[:, O_PX] - ego[PX], block[:, O_PY] - ego[PY]), kind="stable")
    others[vehicles], kappa[vehicles] = block[order], block_kappa[order]
    return Samples(sample.ego[row:row + 1].copy(), others[None], kappa[None],
                   sample.path[row:row + 1].copy(), sample.stop[row:row + 1].copy())


def standing_car_copies(samples: Samples, path: CandidatePath, share: float, gap_range_m: tuple[float, float],
                        rng: np.random.Generator, stoppable: bool = False) -> Samples:
    """Copies of a ``share`` of ``samples`` (all recorded on ``path``), each with a standing car ahead:
    a gap drawn from ``gap_range_m``, bumper to bumper, or with ``stoppable`` beyond the ego's braking
    distance (so the same draws place the car farther ahead)."""
    if share <= 0.0 or len(samples.ego) == 0:
        return Samples.empty()
    chosen = np.flatnonzero(rng.random(len(samples.ego)) < share)
    gaps = rng.uniform(*gap_range_m, size=len(chosen))
    if stoppable and len(chosen):
        ego = samples.ego[chosen]
        gaps = gaps + braking_distance_m(ego[:, VX], ego[:, ACC])
    return Samples.concat([with_standing_car(samples, int(i), path, float(g)) for i, g in zip(chosen, gaps)])
