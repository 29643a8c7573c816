"""Cam lift functions: the paper's circular single-acting cam and its elliptical double-acting cam.

The cam lifts the vial's platform by the lift y(α) above its lowest-mean
position, so the vial centre is at l − r_d + y(α) (eq. 1b), with α = α0 + ω_v t
the cam (motor) phase:

* single-acting, circular eccentric (the paper's mill): y = r_d sin α — one
  stroke per cam revolution;
* double-acting, elliptical (the paper's proposal, "Cam design"): y = r_d sin 2α —
  two strokes of the same height 2 r_d per cam revolution.

Both are one harmonic, y = r_d sin(h α) with h strokes per revolution, so the
physics runs unchanged on the *lift* phase h·α and the *lift* frequency h·ω_v:
every formula of eqs 1–27 that has ω_v and α of the circular cam takes
:func:`lift_speed_rad_s` and :func:`lift_phase_rad` instead (kinematics,
detachment, flight, events, limits, telemetry, the node). The spring
deformation of eqs 4 and 27 is the lift itself, z = y.

An ellipse with semi-axes a > b turning under a flat follower lifts it by its
support function √(a² cos² φ + b² sin² φ) = (a + b)/2 + ((a − b)/2) cos 2φ + O((a − b)²/(a + b)):
the required half stroke r_d fixes a − b = 2 r_d, and the eccentricity follows
from the cam's mean radius R̄ = (a + b)/2 (:func:`ellipse_for_amplitude`). The
double-acting lift above is that second harmonic; the neglected higher
harmonics are of relative size (a − b)/(a + b) = r_d/R̄ (docs/model.md#cam-shapes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from millctl.config.models import CamShape
from millctl.errors import PhysicsInputError

STROKES_PER_REVOLUTION = {CamShape.SINGLE: 1, CamShape.DOUBLE: 2}
"""h: lift strokes per cam revolution."""


def strokes(shape: CamShape) -> int:
    """h, the number of lift strokes per cam revolution (1 circular, 2 elliptical)."""
    return STROKES_PER_REVOLUTION[CamShape(shape)]


def lift_speed_rad_s(shape: CamShape, omega_v_rad_s: float) -> float:
    """Angular frequency of the lift, h·ω_v (rad/s), from the cam (motor) speed."""
    return strokes(shape) * omega_v_rad_s


def lift_speed_array(shape: CamShape, omega_v_rad_s: ArrayLike) -> NDArray[np.float64]:
    """Vectorised :func:`lift_speed_rad_s`."""
    return strokes(shape) * np.asarray(omega_v_rad_s, dtype=float)


def lift_phase_rad(shape: CamShape, alpha_rad: float) -> float:
    """Phase of the lift, h·α (rad), from the cam (motor) phase."""
    return strokes(shape) * alpha_rad


def lift_m(shape: CamShape, eccentricity_m: float, alpha_rad: float) -> float:
    """Cam lift y(α) = r_d sin(h α) (m) at cam phase α; z of eqs 4 and 27."""
    return eccentricity_m * math.sin(strokes(shape) * alpha_rad)


@dataclass(frozen=True)
class Ellipse:
    """The elliptical double-acting cam that gives a half stroke r_d at a mean radius R̄ (m)."""

    semi_major_m: float
    semi_minor_m: float
    eccentricity: float
    """e = √(1 − b²/a²)."""
    harmonic_error: float
    """Relative size r_d/R̄ of the lift harmonics that the one-harmonic lift neglects."""


def ellipse_for_amplitude(eccentricity_m: float, mean_radius_m: float) -> Ellipse:
    """Semi-axes a = R̄ + r_d, b = R̄ − r_d (so that a − b = 2 r_d) and the ellipse's eccentricity."""
    if not (math.isfinite(mean_radius_m) and mean_radius_m > eccentricity_m >= 0.0):
        raise PhysicsInputError(
            f"cam mean radius {mean_radius_m} m must exceed the half stroke r_d = {eccentricity_m} m "
            "(docs/model.md#cam-shapes)"
        )
    a, b = mean_radius_m + eccentricity_m, mean_radius_m - eccentricity_m
    return Ellipse(a, b, math.sqrt(1.0 - (b / a) ** 2), eccentricity_m / mean_radius_m)


__all__ = [
    "STROKES_PER_REVOLUTION",
    "Ellipse",
    "ellipse_for_amplitude",
    "lift_m",
    "lift_phase_rad",
    "lift_speed_array",
    "lift_speed_rad_s",
    "strokes",
]
