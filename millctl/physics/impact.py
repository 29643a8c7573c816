"""Impact frequency and energy (eqs 18–19) and shear stresses (eqs 20–27), paper and corrected.

Corrected forms (docs/model.md, errata):

* eq. 18 counts impacts per rod; the mill's rate is n·p·ω_r/2π;
* eq. 19 uses the absolute speed; an impact dissipates ½ m_eff (1 − e²) v_n², with
  v_n the relative normal velocity, m_eff = m against the wall or a rod held by it,
  m/2 between two flying rods;
* eq. 23: Hertz line contact b = √(4 N R' / (π L E*)), 1/E* = (1 − ν₁²)/E₁ + (1 − ν₂²)/E₂
  (printed: E₂ twice and π/4);
* eq. 24: a rod inside a bore is a concave contact, 1/R' = 1/R_r − 1/R_v (printed: a sum).
"""

from __future__ import annotations

import math

from millctl.config.models import ModelVariant
from millctl.physics.model import MillModel


def impact_rate_hz(model: MillModel, collisions_per_rod_rev: float, omega_r_rad_s: float) -> float:
    """Impact rate (Hz): paper eq. 18 p·ω_r/2π (per rod, as printed), corrected n·p·ω_r/2π (whole mill)."""
    per_rod = collisions_per_rod_rev * omega_r_rad_s / (2.0 * math.pi)
    return per_rod if model.variant is ModelVariant.PAPER else model.n_rods * per_rod


def impact_energy_j(model: MillModel, normal_velocity_m_s: float, speed_abs_m_s: float, backed: bool) -> float:
    """Energy of one impact (J): paper eq. 19 ½ m |v|²; corrected ½ m_eff (1 − e²) v_n².

    ``backed``: the partner is the wall or a rod held by it (m_eff = m); False for
    a flying partner of equal mass (m_eff = m/2).
    """
    m = model.rod_mass_kg
    if model.variant is ModelVariant.PAPER:
        return 0.5 * m * speed_abs_m_s**2
    m_eff = m if backed else 0.5 * m
    return 0.5 * m_eff * (1.0 - model.restitution**2) * normal_velocity_m_s**2


def effective_modulus_pa(model: MillModel) -> float:
    """E* of the rod–vial pair (Pa): corrected 1/E* = (1 − ν₁²)/E₁ + (1 − ν₂²)/E₂; paper eq. 23 uses E₂ twice."""
    rod_e = model.vial_youngs_pa if model.variant is ModelVariant.PAPER else model.rod_youngs_pa
    return 1.0 / ((1.0 - model.rod_poisson**2) / rod_e + (1.0 - model.vial_poisson**2) / model.vial_youngs_pa)


def contact_radius_m(model: MillModel) -> float:
    """R' of the rod–bore contact (m): corrected 1/R' = 1/R_r − 1/R_v (concave), paper eq. 24 1/r = 1/R_r + 1/R_v."""
    r_r, r_v = model.rod_radius_m, model.vial_radius_m
    if model.variant is ModelVariant.PAPER:
        return 1.0 / (1.0 / r_r + 1.0 / r_v)
    return 1.0 / (1.0 / r_r - 1.0 / r_v)


def hertz_half_width_m(model: MillModel, normal_force_n: float) -> float:
    """Half-width b of the line contact (m), eq. 23: corrected √(4 N R'/(π L E*)), paper √((π/4) N r/(L E*))."""
    n = max(normal_force_n, 0.0)
    e_star, r = effective_modulus_pa(model), contact_radius_m(model)
    factor = math.pi / 4.0 if model.variant is ModelVariant.PAPER else 4.0 / math.pi
    return math.sqrt(factor * n * r / (model.rod_length_m * e_star))


def mean_pressure_pa(model: MillModel, normal_force_n: float) -> float:
    """Average contact pressure p_av = N/(2 L b) (Pa), eq. 22; 0 without load."""
    b = hertz_half_width_m(model, normal_force_n)
    return normal_force_n / (2.0 * model.rod_length_m * b) if b > 0.0 else 0.0


def peak_pressure_pa(model: MillModel, normal_force_n: float) -> float:
    """Peak contact pressure p_max = 2N/(π L b) (Pa), eq. 21; 0 without load."""
    b = hertz_half_width_m(model, normal_force_n)
    return 2.0 * normal_force_n / (math.pi * model.rod_length_m * b) if b > 0.0 else 0.0


def wall_shear_pa(model: MillModel, normal_force_n: float) -> float:
    """Shear on the powder between a pinned rod and the wall, τ = μ p_av (Pa), eq. 25."""
    return model.powder_friction * mean_pressure_pa(model, normal_force_n)


def spin_shear_pa(model: MillModel, normal_force_n: float, sin_alpha: float, theta_rad: float) -> float:
    """Shear from the spring couple, eq. 27: k r_d sin α sin(π/2 − θ) / (2 L b) (Pa), at the wall load N."""
    b = hertz_half_width_m(model, normal_force_n)
    if b <= 0.0:
        return 0.0
    force = model.spring_n_per_m * model.eccentricity_m * sin_alpha * math.cos(theta_rad)
    return force / (2.0 * model.rod_length_m * b)


def rod_rod_shear_pa(model: MillModel, weight_component_n: float, contact_area_m2: float) -> float:
    """Shear between two colliding rods, eq. 20: μ W_r / A (Pa)."""
    if contact_area_m2 <= 0.0:
        return 0.0
    return model.powder_friction * weight_component_n / contact_area_m2


__all__ = [
    "contact_radius_m",
    "effective_modulus_pa",
    "hertz_half_width_m",
    "impact_energy_j",
    "impact_rate_hz",
    "mean_pressure_pa",
    "peak_pressure_pa",
    "rod_rod_shear_pa",
    "spin_shear_pa",
    "wall_shear_pa",
]
