"""Impact frequency and energy (eqs 18–19) and shear stresses (eqs 20–27), paper and corrected.

Corrected forms (docs/model.md, errata):

* eq. 18 counts impacts per rod; the mill's rate is n·p·ω_r/2π;
* eq. 19 uses the absolute speed; an impact dissipates ½ m_eff (1 − e²) v_n², with
  v_n the relative normal velocity, m_eff = m against the wall or a rod held by it,
  m/2 between two flying rods;
* eq. 23: Hertz line contact b = √(4 N R' / (π L E*)), 1/E* = (1 − ν₁²)/E₁ + (1 − ν₂²)/E₂
  (printed: E₂ twice and π/4);
* eq. 24: a rod inside a bore is a concave contact, 1/R' = 1/R_r − 1/R_v (printed: a sum);
* eq. 20: the area A is the Hertz line contact of the two colliding rods, A = 2 b L with
  R' = r_r/2 (two equal convex cylinders) and 1/E* = 2(1 − ν²)/E (both rods), so that
  τ = μ W_r/A = μ p_av of that contact (printed: A undefined);
* eqs 26–27: the spring acts on the platform, not on the rod. What the wall transmits
  tangentially to a carried rod is the traction F_t = m g_eff cos θ, and at most μN of it:
  τ = min(|F_t|, μN)/(2 L b) (printed: k r_d sin α cos θ/(2 L b)).
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


def rod_rod_contact_area_m2(model: MillModel, load_n: float) -> float:
    """A of eq. 20 (m²): the Hertz strip 2 b L of two equal rods pressed by ``load_n``.

    b = √(4 W R'/(π L E*)), R' = r_r/2 (1/R' = 1/r_r + 1/r_r, both convex),
    1/E* = 2 (1 − ν²)/E with the rods' own modulus and Poisson ratio.
    """
    w = max(load_n, 0.0)
    e_star = model.rod_youngs_pa / (2.0 * (1.0 - model.rod_poisson**2))
    r_eff = 0.5 * model.rod_radius_m
    b = math.sqrt(4.0 * w * r_eff / (math.pi * model.rod_length_m * e_star))
    return 2.0 * b * model.rod_length_m


def rod_rod_weight_shear_pa(model: MillModel, weight_component_n: float) -> float:
    """Eq. 20 with its area defined: τ = μ W_r / A(W_r), the Hertz strip of the colliding rods (Pa)."""
    return rod_rod_shear_pa(model, weight_component_n, rod_rod_contact_area_m2(model, weight_component_n))


def carriage_shear_pa(
    model: MillModel, omega_r_rad_s: float, omega_v_rad_s: float, theta_rad: float, alpha_rad: float
) -> tuple[float, float]:
    """Eqs 26–27 corrected: shear the wall transmits to a carried rod, (uncapped, capped at μN) in Pa.

    N = m (r0 ω_r² − g_eff sin θ), F_t = m g_eff cos θ, g_eff = g − r_d ω_v² sin α; the strip is 2 b(N) L
    (eq. 23 corrected). Uncapped |F_t|/(2 L b) is what the no-slip carriage needs; the wall gives at most
    μN/(2 L b) = μ p_av (eq. 25), and where the first exceeds the second the rod slides (docs/model.md, slip).
    Both 0 where N ≤ 0 (the rod is off the wall).
    """
    m = model.rod_mass_kg
    g_eff = model.g_m_s2 - model.eccentricity_m * omega_v_rad_s**2 * math.sin(alpha_rad)
    normal = m * (model.r0_m * omega_r_rad_s**2 - g_eff * math.sin(theta_rad))
    b = hertz_half_width_m(model, normal)
    if normal <= 0.0 or b <= 0.0:
        return 0.0, 0.0
    traction = abs(m * g_eff * math.cos(theta_rad))
    strip = 2.0 * model.rod_length_m * b
    return traction / strip, min(traction, model.powder_friction * normal) / strip


__all__ = [
    "carriage_shear_pa",
    "contact_radius_m",
    "effective_modulus_pa",
    "hertz_half_width_m",
    "impact_energy_j",
    "impact_rate_hz",
    "mean_pressure_pa",
    "peak_pressure_pa",
    "rod_rod_contact_area_m2",
    "rod_rod_shear_pa",
    "rod_rod_weight_shear_pa",
    "spin_shear_pa",
    "wall_shear_pa",
]
