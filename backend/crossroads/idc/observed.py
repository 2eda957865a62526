"""x_other of an observation, with each participant's route curvature (what f_other predicts from).

The online decision needs only x_other; the training sampler and the safety shield also roll the
participants forward with f_other, which turns each by its route's curvature 1/R (SPEC §5). Both are
ordered and padded the same way (``idc.state.select_others``): the closest 8 vehicles, 4 cyclists
and 4 pedestrians the sensors cover; pads get κ = 0.
"""

from __future__ import annotations

import numpy as np

from crossroads.idc.state import select_others
from crossroads.sim.world import Observation, participant_curvatures


def observed_others(obs: Observation) -> tuple[np.ndarray, np.ndarray]:
    """(x_other (16, 6), κ (16,)) of the participants ``obs`` perceives."""
    seen = obs.perceived
    others = select_others(obs.ego, seen.observations, seen.kinds)
    kappa_rows = np.array(seen.observations, dtype=np.float64, copy=True).reshape(-1, 6)
    kappa_rows[:, 2] = participant_curvatures(obs.lane_shapes, obs.participants, seen.rows)
    kappa = select_others(obs.ego, kappa_rows, seen.kinds)[:, 2]  # pads: speed 0 → κ 0
    return others, kappa
