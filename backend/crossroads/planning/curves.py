"""How tight the paper's Bezier curve bends for each ρ, and which ρ to draw it with.

The curve route of a candidate path is the paper's cubic Bezier X1, X2, X3, X4 with the inner
control points of its closed form (:func:`crossroads.geometry.bezier_control_points_closed_form`):
X2 = X1 + (1 − ρ)·a and X3 = X4 − (1 − ρ)·b, where a is the chord X1→X4 projected onto the entrance
direction and b the chord projected onto the exit direction. ρ sets how long the two handles are:
the paper's ρ = 0.6 bends right turns into inner lanes and turns of more than 90° far tighter than
the ego can steer (up to 0.8 1/m on the catalogue's intersections).

The ego turns no tighter than its wheelbase and steering limit allow: curvature
:data:`MAX_CURVATURE` = tan(0.4 rad) / 2.65 m = 0.16 1/m (radius 6.25 m). **(choice, deviation
from the paper, SPEC §1)** ρ is chosen per candidate: the paper's ρ when its curve stays within
:data:`PAPER_RHO_MAX_CURVATURE` (four fifths of the limit: full lock leaves no steering to correct
an error with), otherwise the ρ of the grid :data:`RHO_GRID` whose curve bends least (the most room
to track it). The curve's shape family is the paper's; only ρ moves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crossroads.constants import L_F, L_R, RHO_BEZIER, STEER_MAX
from crossroads.geometry import FloatArray, unit

# [1/m] the tightest curve the ego can follow: kinematic bicycle at full lock, tan(δ_max) / wheelbase
MAX_CURVATURE = math.tan(STEER_MAX) / (L_F + L_R)
# [1/m] the paper's ρ is kept where its curve bends no more than this (choice): a fifth of the
# steering range left for corrections
PAPER_RHO_MAX_CURVATURE = 0.8 * MAX_CURVATURE
# ρ tried per candidate (choice): (0, 1) without its ends, where the handles vanish (ρ → 1, a corner)
# or reach the foot of the other end point (ρ → 0)
RHO_GRID: FloatArray = np.round(np.arange(0.05, 0.9501, 0.01), 2)
# parameter samples on which a curve's curvature is judged: 401 steps of 0.0025 catch the peak of
# every curve of the catalogue within 0.1 % of the 4001-sample value
_T = np.linspace(0.0, 1.0, 401)
CURVATURE_TOLERANCE = 1e-6  # [1/m] a curve this close above the limit counts as within it


@dataclass(frozen=True)
class RhoChoice:
    """One ρ and the largest |curvature| [1/m] of its curve."""

    rho: float
    max_curvature: float

    @property
    def within_limit(self) -> bool:
        return self.max_curvature <= MAX_CURVATURE + CURVATURE_TOLERANCE


def max_curvatures(x1: FloatArray, x4: FloatArray, theta_in: float, theta_out: float,
                   rhos: FloatArray) -> FloatArray:
    """The largest |curvature| [1/m] of the paper's Bezier for every ρ of ``rhos`` (vectorised;
    ``inf`` where the curve has a cusp).

    With h = 1 − ρ, B'(t) = h·P(t) + Q(t) and B''(t) = h·R(t) + S(t) for curves P, Q, R, S that
    do not depend on ρ, so the cross product B' × B'' and |B'|² are quadratics in h: one outer
    product per term instead of the Bezier's derivatives once per ρ.
    """
    p1, p4 = np.asarray(x1, float), np.asarray(x4, float)
    chord = p4 - p1
    d_in, d_out = unit(theta_in), unit(theta_out)
    a = d_in * float(chord @ d_in)  # X2 − X1 at ρ = 0
    b = d_out * float(chord @ d_out)  # X4 − X3 at ρ = 0
    t = _T[:, None]
    u = 1.0 - t
    # B' = 3u²(X2−X1) + 6tu(X3−X2) + 3t²(X4−X3), X2−X1 = h·a, X4−X3 = h·b, X3−X2 = chord − h(a+b)
    big_p = 3.0 * u**2 * a - 6.0 * t * u * (a + b) + 3.0 * t**2 * b  # (T, 2)
    big_q = 6.0 * t * u * chord
    # B'' = 6u(X3 − 2X2 + X1) + 6t(X4 − 2X3 + X2)
    big_r = -6.0 * u * (2.0 * a + b) + 6.0 * t * (a + 2.0 * b)
    big_s = 6.0 * u * chord - 6.0 * t * chord

    def cross(v: FloatArray, w: FloatArray) -> FloatArray:
        return v[:, 0] * w[:, 1] - v[:, 1] * w[:, 0]

    h = (1.0 - np.asarray(rhos, float))[:, None]  # (K, 1)
    c2, c1, c0 = cross(big_p, big_r), cross(big_p, big_s) + cross(big_q, big_r), cross(big_q, big_s)
    numerator = np.abs(h**2 * c2 + h * c1 + c0)  # (K, T)
    speed2 = h**2 * np.einsum("ij,ij->i", big_p, big_p) + 2.0 * h * np.einsum("ij,ij->i", big_p, big_q) \
        + np.einsum("ij,ij->i", big_q, big_q)
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(speed2 > 1e-18, numerator / np.maximum(speed2, 1e-300) ** 1.5, np.inf)
    return kappa.max(axis=1)


def rho_preferences(x1: FloatArray, x4: FloatArray, theta_in: float, theta_out: float
                    ) -> list[RhoChoice]:
    """Every ρ worth trying for one curve, best first: the paper's ρ when its curve bends no more
    than :data:`PAPER_RHO_MAX_CURVATURE`, then the grid's ρ from the least bent curve to the most
    bent one (ties: the one nearer the paper's ρ)."""
    grid = max_curvatures(x1, x4, theta_in, theta_out, RHO_GRID)
    order = sorted(range(len(RHO_GRID)),
                   key=lambda i: (float(grid[i]), abs(float(RHO_GRID[i]) - RHO_BEZIER)))
    choices = [RhoChoice(float(RHO_GRID[i]), float(grid[i])) for i in order]
    paper = RhoChoice(RHO_BEZIER, float(max_curvatures(x1, x4, theta_in, theta_out,
                                                       np.array([RHO_BEZIER]))[0]))
    return [paper, *choices] if paper.max_curvature <= PAPER_RHO_MAX_CURVATURE else choices
