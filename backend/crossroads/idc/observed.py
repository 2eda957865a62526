"""x_other of an observation, with each participant's route curvature (what f_other predicts from).

The online decision needs only x_other; the training sampler and the safety shield also roll the
participants forward with f_other, which turns each by its route's curvature 1/R (SPEC §5). Both are
ordered and padded the same way (``idc.state.select_others``): the closest 8 vehicles, 4 cyclists
and 4 pedestrians the sensors cover; pads get κ = 0.
"""

from __future__ import annotations

import numpy as np

from crossroads.idc.state import N_OTHERS, others_in_slots, selected_rows
from crossroads.sim.observation import Observation, participant_curvatures


def observed_others(obs: Observation) -> tuple[np.ndarray, np.ndarray]:
    """(x_other (16, 6), κ (16,)) of the participants ``obs`` perceives. The curvature is computed
    for the 16 participants in the slots only, not for all ~100 perceived (it walks each one's lane:
    0.48 ms a step for all of them, about a third of what the shield added to a decision)."""
    seen = obs.perceived
    slots = selected_rows(obs.ego, seen.observations, seen.slot_kinds())
    others = others_in_slots(obs.ego, seen.observations, slots)
    taken = slots >= 0
    kappa = np.zeros(N_OTHERS)  # pads: κ 0
    chosen = slots[taken]
    kappa[taken] = participant_curvatures(obs.lane_shapes, seen.lanes(chosen), seen.observations[chosen],
                                          seen.kinds[chosen])
    return others, kappa
