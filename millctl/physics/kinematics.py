"""Kinematics of a rod carried by the wall (eqs 1–3) and the normal-force function (eqs 4–7).

Lab frame: origin at the cam rotor, y up. The vial centre is
c(t) = (0, l − r_d + r_d sin α) with α = α0 + ω_v t, and a rod pinned to the wall
sits at c + r0 (cos θ, sin θ), θ = θ0 + ω_r t — eqs 1a/1b with arbitrary phases.

The normal force per unit mass, as a function of time, is a constant plus three
cosines, which gives exact derivatives and exact bounds on them (used by
:mod:`millctl.physics.detachment`):

* corrected: N/m = r0 ω_r² − g_eff sin θ, g_eff = g − r_d ω_v² sin α;
* paper (printed eq. 7 as a root in time): N/m = 2 r0 ω_r² − (g + (k/m − ω_v²) r_d sin α) sin θ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from millctl.config.models import ModelVariant
from millctl.physics.model import Scene

FloatArray = NDArray[np.float64]


def vial_centre_m(scene: Scene, t_s: float) -> tuple[float, float, float]:
    """Vial centre height y_c (m), its velocity (m/s) and acceleration (m/s²) at time t (eq. 1b's cam term)."""
    m = scene.model
    alpha = scene.lift_alpha0_rad + scene.lift_omega_rad_s * t_s
    r_d, w = m.eccentricity_m, scene.lift_omega_rad_s
    y = m.cam_to_vial_m - r_d + r_d * math.sin(alpha)
    return y, r_d * w * math.cos(alpha), -r_d * w * w * math.sin(alpha)


def rod_on_wall(scene: Scene, t_s: float, theta0_rad: float | None = None) -> tuple[float, ...]:
    """Position, velocity and acceleration (x, y, vx, vy, ax, ay; SI) of a pinned rod, eqs 1–3."""
    m = scene.model
    theta = (scene.theta0_rad if theta0_rad is None else theta0_rad) + scene.omega_r_rad_s * t_s
    yc, vyc, ayc = vial_centre_m(scene, t_s)
    r0, w = m.r0_m, scene.omega_r_rad_s
    c, s = math.cos(theta), math.sin(theta)
    return (r0 * c, yc + r0 * s, -r0 * w * s, vyc + r0 * w * c, -r0 * w * w * c, ayc - r0 * w * w * s)


def g_eff_m_s2(scene: Scene, t_s: float) -> float:
    """Effective gravity in the vial frame, g − r_d ω_v² sin α (m/s²)."""
    m = scene.model
    alpha = scene.lift_alpha0_rad + scene.lift_omega_rad_s * t_s
    return m.g_m_s2 - m.eccentricity_m * scene.lift_omega_rad_s**2 * math.sin(alpha)


@dataclass(frozen=True)
class TrigSum:
    """f(t) = c + Σ a_i cos(w_i t + φ_i), with exact derivatives and bounds on them."""

    constant: float
    amplitudes: tuple[float, ...]
    frequencies_rad_s: tuple[float, ...]
    phases_rad: tuple[float, ...]

    def __call__(self, t_s: float, order: int = 0) -> float:
        """The ``order``-th time derivative at t."""
        total = self.constant if order == 0 else 0.0
        shift = 0.5 * math.pi * order
        for a, w, p in zip(self.amplitudes, self.frequencies_rad_s, self.phases_rad, strict=True):
            total += a * w**order * math.cos(w * t_s + p + shift)
        return total

    def on_grid(self, t_s: FloatArray, order: int = 0) -> FloatArray:
        """Vectorised ``order``-th derivative on an array of times."""
        a = np.asarray(self.amplitudes) * np.asarray(self.frequencies_rad_s) ** order
        arg = np.outer(self.frequencies_rad_s, t_s) + (np.asarray(self.phases_rad) + 0.5 * math.pi * order)[:, None]
        result: FloatArray = (self.constant if order == 0 else 0.0) + a @ np.cos(arg)
        return result

    def bound(self, order: int) -> float:
        """An upper bound on |f^(order)| over all t (order ≥ 1)."""
        return sum(abs(a) * abs(w) ** order for a, w in zip(self.amplitudes, self.frequencies_rad_s, strict=True))


def normal_force_per_mass(scene: Scene, theta0_rad: float, variant: ModelVariant | None = None) -> TrigSum:
    """N(t)/m (m/s²) of a rod pinned at θ0 + ω_r t, in the given variant (default: the model's).

    Uses sin α sin θ = ½[cos(α − θ) − cos(α + θ)] and −g sin θ = g cos(θ + π/2).
    """
    m = scene.model
    variant = m.variant if variant is None else variant
    w_r, w_v, a0 = scene.omega_r_rad_s, scene.lift_omega_rad_s, scene.lift_alpha0_rad
    if variant is ModelVariant.CORRECTED:
        constant = m.r0_m * w_r * w_r
        coupling = m.eccentricity_m * w_v * w_v  # + r_d ω_v² sin α sin θ
    else:
        constant = 2.0 * m.r0_m * w_r * w_r
        coupling = (w_v * w_v - m.spring_n_per_m / m.rod_mass_kg) * m.eccentricity_m
    half = 0.5 * coupling
    return TrigSum(
        constant=constant,
        amplitudes=(m.g_m_s2, half, -half),
        frequencies_rad_s=(w_r, w_v - w_r, w_v + w_r),
        phases_rad=(theta0_rad + 0.5 * math.pi, a0 - theta0_rad, a0 + theta0_rad),
    )


def true_normal_force_per_mass(scene: Scene, t_s: float, theta_rad: float) -> float:
    """The corrected N/m (m/s²) at time t for a rod at angle θ: r0 ω_r² − g_eff sin θ."""
    return scene.model.r0_m * scene.omega_r_rad_s**2 - g_eff_m_s2(scene, t_s) * math.sin(theta_rad)


__all__ = [
    "TrigSum",
    "g_eff_m_s2",
    "normal_force_per_mass",
    "rod_on_wall",
    "true_normal_force_per_mass",
    "vial_centre_m",
]
