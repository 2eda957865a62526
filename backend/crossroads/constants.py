"""Every number of the paper (docs/paper.md) in one place, with its unit and its source.

Nothing here is ever reassigned at run time: configurable values (ρ of the planner, V_limit, traffic
densities, ...) take these as their defaults. Sections ("§4", "SPEC §4" elsewhere in the code) are
those of docs/paper.md; "(choice)" marks a project decision where the paper is silent.
"""

from __future__ import annotations

import math
from typing import Final

KMH: Final = 1.0 / 3.6  # [m/s per km/h]

# --- §1 Static path planner (Sec. III-A) -------------------------------------------------------
RHO_BEZIER: Final = 0.6  # [-] ρ-division of X1–X4 that places the Bezier control points X2, X3
V_LIMIT_MPS: Final = 37.5 * KMH  # [m/s] V_limit used by the velocity planning
PASS_SPEED_FACTOR_OUTSIDE: Final = 0.8  # [-] pass mode outside the intersection: 0.8·V_limit
PASS_SPEED_FACTOR_INSIDE: Final = 0.5  # [-] pass mode inside: min(0.5·V_limit, 30 km/h)
INSIDE_SPEED_CAP_MPS: Final = 30.0 * KMH  # [m/s] Chinese rule for speeds inside intersections
STOP_DECEL_DISTANCE_M: Final = 30.0  # [m] stop mode decelerates uniformly to 0 over this distance
PATH_SAMPLE_SPACING_M: Final = 0.5  # [m] maximal spacing of the sampled candidate polylines

# --- §2 Traffic and signals (Sec. IV-A) ---------------------------------------------------------
VEHICLES_PER_HOUR_PER_LANE: Final = 400.0  # [veh/h] per entrance lane
CYCLISTS_PER_HOUR_PER_LANE: Final = 100.0  # [bic/h] per entrance lane
PEDESTRIANS_PER_HOUR_PER_LANE: Final = 100.0  # [ped/h] per entrance lane
GREEN_S: Final = 60.0  # [s] green of the ego's axis
YELLOW_S: Final = 3.0  # [s] yellow after every green
RED_S: Final = 40.0  # [s] red seen by the ego's approach
# [s] (choice) an all-red after every yellow, as real signals give: a left-turner waiting inside
# the junction clears before the cross traffic starts (without it, the left-turner at the head of
# c_three_lane's queue was seen standing on through the cross axis' green)
ALL_RED_S: Final = 2.0
# [s] (choice) the cross axis' green: AR2/G33/Y3/AR2, so the ego still sees R40
CROSS_GREEN_S: Final = RED_S - YELLOW_S - 2.0 * ALL_RED_S
# [s] (choice) a crossing's walk ends this long before the parallel vehicles' green does (the
# pedestrian clearance of real signals): the crossing empties and the turners that yield to it go
PEDESTRIAN_CLEARANCE_S: Final = 10.0
CYCLE_S: Final = GREEN_S + YELLOW_S + ALL_RED_S + CROSS_GREEN_S + YELLOW_S + ALL_RED_S  # [s] 103
SIM_STEP_S: Final = 0.1  # [s] SUMO step and control period (Δt of f_ego)

# Kinds of traffic participants, in the order of x_other (SPEC §4) and of every kind code.
PARTICIPANT_KINDS: Final = ("vehicle", "cyclist", "pedestrian")

# --- §3 Perception (Sec. IV-B) ------------------------------------------------------------------
LIDAR_RANGE_M: Final = 70.0
LIDAR_FOV_DEG: Final = 360.0
CAMERA_RANGE_M: Final = 80.0
CAMERA_FOV_DEG: Final = 70.0  # ±35°
RADAR_RANGE_M: Final = 60.0
RADAR_FOV_DEG: Final = 90.0  # ±45°
RADAR_CORNER_YAW_DEG: Final = 45.0  # (choice) the two corner radars face ±45° outward

# Gaussian noise (mean, std) of the observation of each participant type, Table "Noise parameters".
# Keys: p_x [m], p_y [m], v [m/s], phi [rad], L [m], W [m].
PERCEPTION_NOISE: Final[dict[str, dict[str, tuple[float, float]]]] = {
    "vehicle": {
        "p_x": (-0.002, 0.157), "p_y": (-0.001, 0.151), "v": (-0.000, 0.205),
        "phi": (0.000, 0.054), "L": (-0.011, 0.300), "W": (0.023, 0.142),
    },
    "cyclist": {
        "p_x": (0.001, 0.172), "p_y": (-0.008, 0.158), "v": (0.005, 0.176),
        "phi": (-0.014, 0.171), "L": (-0.003, 0.165), "W": (0.035, 0.109),
    },
    "pedestrian": {
        "p_x": (0.001, 0.110), "p_y": (-0.001, 0.111), "v": (-0.000, 0.119),
        "phi": (-0.003, 0.229), "L": (-0.000, 0.147), "W": (-0.002, 0.141),
    },
}

# --- §4 State, action, utility (Sec. IV-C) -----------------------------------------------------
N_VEHICLES_OBSERVED: Final = 8
N_CYCLISTS_OBSERVED: Final = 4
N_PEDESTRIANS_OBSERVED: Final = 4
EGO_STATE_DIM: Final = 8  # [p_x, p_y, v_x, v_y, φ, ω, δ, a]
TRACK_STATE_DIM: Final = 4  # [Δx, Δy, Δv, Δφ]
OTHER_STATE_DIM: Final = 6  # [p_x, p_y, v, φ, L, W] per participant
STATE_DIM: Final = EGO_STATE_DIM + TRACK_STATE_DIM + OTHER_STATE_DIM * (
    N_VEHICLES_OBSERVED + N_CYCLISTS_OBSERVED + N_PEDESTRIANS_OBSERVED
)  # 108
# (choice, not the paper's) The path preview that networks built with ``path_preview`` read after
# the 108 values (idc.state): the reference 5-20 m ahead along the candidate path, since the
# paper's x_track holds the nearest point only and the networks drop the ego's absolute pose.
PREVIEW_DISTANCES_M: Final = (5.0, 10.0, 15.0, 20.0)  # [m] of arc length beyond the nearest point
PREVIEW_FEATURES: Final = 3  # per distance: lateral offset in the ego frame, relative heading, v_ref
PREVIEW_DIM: Final = PREVIEW_FEATURES * len(PREVIEW_DISTANCES_M)  # 12
# (choice, not the paper's) The lead summary that networks built with ``lead_input`` read after the
# state (idc.state.lead_features): the nearest participant in a straight corridor ahead of the ego,
# whichever of the 16 distance-sorted slots it sits in.
LEAD_LOOKAHEAD_M: Final = 40.0  # [m] how far ahead the corridor reaches (and the gap when it is empty)
LEAD_LATERAL_MARGIN_M: Final = 0.3  # [m] added to the two half widths: the corridor's lateral reach
LEAD_DIM: Final = 3  # gap / lookahead, closing speed / 10 m/s, 1 when a participant is in the corridor
STEER_RATE_MAX: Final = 0.4  # [rad/s] |Δδ|
JERK_MAX: Final = 4.5  # [m/s³] |Δa|
STEER_MAX: Final = 0.4  # [rad] |δ|
ACCEL_MIN: Final = -3.0  # [m/s²]
ACCEL_MAX: Final = 1.5  # [m/s²]

UTILITY_WEIGHTS: Final[dict[str, float]] = {
    "dv": 0.03, "dx": 0.8, "dy": 0.8, "dphi": 30.0,
    "omega": 0.02, "delta": 5.0, "a": 0.05, "ddelta": 0.4, "da": 0.1,
}

# --- §5 Models (Sec. IV-D) ----------------------------------------------------------------------
K_F: Final = -155495.0  # [N/rad] front cornering stiffness
K_R: Final = -155495.0  # [N/rad] rear cornering stiffness
L_F: Final = 1.19  # [m] CG to front axle
L_R: Final = 1.46  # [m] CG to rear axle
MASS_KG: Final = 1520.0  # [kg]
I_Z: Final = 2642.0  # [kg·m²]
DT_S: Final = SIM_STEP_S  # [s] discrete time of f_ego / f_other
# (choice) How hard a surrounding participant may brake in the predictions that assume it does (the
# safety shield's second future, the training model's braking floor): SUMO's default passenger-car decel
OTHER_DECEL_MPS2: Final = 4.5  # [m/s²]
# (choice) the ego's footprint, a mid-size car around the paper's 2.65 m wheelbase (L_f + L_r).
# Used for its SUMO vehicle, the true-footprint collision check and the safety circles.
EGO_LENGTH_M: Final = 4.8  # [m]
EGO_WIDTH_M: Final = 2.0  # [m]
# (choice) How far SUMO's internal lane of a movement may run from the movement's candidate path
# before the tool warns about the net (`crossroads net check`, uploads, `crossroads evaluate`):
# half the ego's width. SUMO puts the ego where it projects onto that internal lane, and its
# junction model and its drivers' leaders see it there; beyond half a car's width that place is
# more than half a car from where the ego drives. netconvert's own lanes on the catalogue's nets
# ran up to 2.55 m off the left turns (docs/tried/world.md); its builds now draw them
# along the paths (intersections/build.py), but a user's net keeps its own.
INTERNAL_LANE_OFFSET_WARN_M: Final = EGO_WIDTH_M / 2.0  # [m]
# (choice) How far before the stop line the stop profile reaches 0: the paths are of the ego's
# centre, and the judge (and the law) mean its front bumper. Without it the stop mode brought the
# centre to rest on the line with the bumper 2.4 m past it: measured, the rule
# controller and APG both crossed a red line on an empty road, at 3.4 and 5.3 m/s.
STOP_SHORT_M: Final = EGO_LENGTH_M / 2.0  # [m]
# (choice) where a controller stands at a line that holds it: its front bumper this far short, so
# that a stop a few cm off SUMO's moves still leaves the bumper behind the line (the rule
# controller's own stop and the safety shield's line, idc.rule_based and idc.shield)
STOP_LINE_GAP_M: Final = 0.5  # [m]

# ξ ranges of the adversary, (low, high): x [m], y [m], v [m/s], φ [rad].
XI_RANGES: Final[dict[str, tuple[float, float]]] = {
    "x": (-0.8, 0.8), "y": (-0.8, 0.8), "v": (-0.075, 0.225), "phi": (-0.025, 0.025),
}

# --- §6 APG training (Algorithm 1, Sec. V-A) ---------------------------------------------------
HORIZON_T: Final = 25
PENALTY_RHO: Final = 15.0
ADVERSARY_UPDATE_INTERVAL: Final = 5
HIDDEN_LAYERS: Final = 5
HIDDEN_UNITS: Final = 256
BATCH_SIZE: Final = 256
POLICY_LR: Final = (1e-4, 2e-6)  # cosine annealing start → end
VALUE_LR: Final = (3e-4, 1e-6)
ADAM_BETAS: Final = (0.9, 0.999)
TOTAL_ITERATIONS: Final = 200_000
LOG_INTERVAL: Final = 1000
TAR_RUNS: Final = 10
TAR_STEPS: Final = 120

# --- §7 Online traffic-light logic (Sec. IV-E) -------------------------------------------------
CONGESTION_STOP_S: Final = 3.0  # [s] front vehicle stopped longer than this → stop mode
YELLOW_BRAKE_DECEL: Final = -2.4  # [m/s²] a_M, 80 % of the maximal braking

# --- §8 Generalization tests (Sec. V-C) --------------------------------------------------------
SURROUNDING_LIMIT_INSIDE_MPS: Final = 25.0 * KMH
SURROUNDING_LIMIT_OUTSIDE_MPS: Final = 30.0 * KMH
OVERSPEED_SHARE: Final = 0.15  # share of the opposite straight vehicles that over-speed
OVERSPEED_LEVELS: Final = (0.10, 0.20, 0.50)
ROUNDING_LEVELS: Final = (0.10, 0.20, 0.50)
EVALUATION_RUNS: Final = 200

DEG: Final = math.pi / 180.0
