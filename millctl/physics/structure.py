"""Structural loads of the mill from its own mechanics: cam, roller, platform springs, shaft bearings, impacts.

Derived in docs/model.md#structural-loads. The cam (eccentricity r_d, lift y = r_d sin hα, lift
frequency ω = hω_v for a cam of h strokes) lifts a roller fixed to the vibrating platform; the four
platform springs (rate K_s together, static extension δ0) join it to the base and pull it back
onto the cam. The platform of mass M (motor, shaft, vial, and the rods, which ride with the wall:
their net force on the vial is n m g_eff downward, the centripetal parts cancel for n ≥ 2) obeys

    M ÿ = F_c − M g − K_s (δ0 + y),   ÿ = −r_d ω² sin hα     (eqs 1b, 3b: the vial's motion)

so the cam–roller contact force is F_c = M g + K_s δ0 + (K_s − M ω²) r_d sin hα, and the roller
leaves the cam (the follower jumps, and lands on it again as an impact) where F_c < 0. Everything
here is a pure, vectorised function of numpy arrays (scalars broadcast), SI units inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from millctl.config.models import G_M_S2, MillConfig
from millctl.physics.cam import strokes

FloatArray = NDArray[np.float64]

LINE_CONTACT_LIFE_EXPONENT = 20.0 / 3.0
"""Contact fatigue life ∝ p_max^(−20/3) for a line contact: Lundberg–Palmgren's L ∝ P^(−10/3) with p_max ∝ √P."""


@dataclass(frozen=True)
class StructureParams:
    """What the structural loads depend on, in SI units (from ``config.mill.structure`` and the mill)."""

    moving_mass_kg: float
    """M: the vibrating platform with its vial and the n rods (kg)."""
    shaft_mass_kg: float
    """What the rotary shaft's bearings carry: vial, holder and the n rods (kg)."""
    rod_mass_kg: float
    n_rods: int
    r0_m: float
    platform_spring_n_per_m: float
    preload_m: float
    eccentricity_m: float
    strokes: int
    """h, lift strokes per cam revolution (1 single-acting, 2 double-acting)."""
    contact_radius_m: float
    """R' of the cam–roller line contact, 1/R' = 1/R_roller + 1/R_cam (both convex)."""
    contact_width_m: float
    contact_modulus_pa: float
    """E* of the cam–roller pair, both of ``structure.cam_material``: E/(2(1 − ν²)) (Pa)."""
    endurance_pa: float
    endurance_cycles: float
    bearing_rating_n: float
    g_m_s2: float = G_M_S2

    @classmethod
    def from_config(cls, config: MillConfig) -> StructureParams:
        """Take the structure, the rods and the cam from a validated configuration."""
        mill, s = config.mill, config.mill.structure
        rods = mill.rods.count * config.rod_mass_kg
        cam = config.materials[s.cam_material]
        e, nu = cam.youngs_modulus_pa, cam.poisson_ratio
        return cls(
            moving_mass_kg=s.platform_mass_kg + rods,
            shaft_mass_kg=s.shaft_mass_kg + rods,
            rod_mass_kg=config.rod_mass_kg,
            n_rods=mill.rods.count,
            r0_m=mill.vial.radius_m - mill.rods.radius_m,
            platform_spring_n_per_m=s.platform_spring_n_per_m,
            preload_m=s.spring_preload_mm * 1e-3,
            eccentricity_m=mill.cam.eccentricity_m,
            strokes=strokes(mill.cam.shape),
            contact_radius_m=1.0 / (1.0 / (s.roller_radius_mm * 1e-3) + 1.0 / (s.cam_radius_mm * 1e-3)),
            contact_width_m=s.contact_width_mm * 1e-3,
            contact_modulus_pa=e / (2.0 * (1.0 - nu * nu)),
            endurance_pa=s.contact_endurance_mpa * 1e6,
            endurance_cycles=s.endurance_cycles,
            bearing_rating_n=s.bearing_rating_n,
        )


def _lift(p: StructureParams, omega_v_rad_s: ArrayLike) -> FloatArray:
    return p.strokes * np.asarray(omega_v_rad_s, dtype=float)


def platform_acceleration_m_s2(p: StructureParams, omega_v_rad_s: ArrayLike, alpha_rad: ArrayLike) -> FloatArray:
    """Vertical acceleration of the platform and vial, ÿ = −r_d (hω_v)² sin hα (m/s², eq. 3b's cam term)."""
    w = _lift(p, omega_v_rad_s)
    return np.asarray(-p.eccentricity_m * w * w * np.sin(p.strokes * np.asarray(alpha_rad, dtype=float)))


def peak_platform_acceleration_m_s2(p: StructureParams, omega_v_rad_s: ArrayLike) -> FloatArray:
    """Peak platform acceleration r_d (hω_v)² = Γ g (m/s²)."""
    w = _lift(p, omega_v_rad_s)
    return np.asarray(p.eccentricity_m * w * w)


def spring_force_n(p: StructureParams, alpha_rad: ArrayLike) -> FloatArray:
    """Tension of the four platform springs together, K_s (δ0 + r_d sin hα) (N); it does not depend on ω_v."""
    y = p.eccentricity_m * np.sin(p.strokes * np.asarray(alpha_rad, dtype=float))
    return np.asarray(p.platform_spring_n_per_m * (p.preload_m + y))


def peak_spring_force_n(p: StructureParams) -> float:
    """Largest spring tension over the stroke, K_s (δ0 + r_d) (N)."""
    return p.platform_spring_n_per_m * (p.preload_m + p.eccentricity_m)


def cam_contact_force_n(p: StructureParams, omega_v_rad_s: ArrayLike, alpha_rad: ArrayLike) -> FloatArray:
    """Cam–roller contact force F_c = M g + K_s δ0 + (K_s − M (hω_v)²) r_d sin hα (N); < 0: the roller lifts off."""
    w = _lift(p, omega_v_rad_s)
    s = np.sin(p.strokes * np.asarray(alpha_rad, dtype=float))
    static = p.moving_mass_kg * p.g_m_s2 + p.platform_spring_n_per_m * p.preload_m
    return np.asarray(static + (p.platform_spring_n_per_m - p.moving_mass_kg * w * w) * p.eccentricity_m * s)


def cam_contact_force_range_n(p: StructureParams, omega_v_rad_s: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """(min, max) of F_c over the cam phase: M g + K_s δ0 ∓ |K_s − M (hω_v)²| r_d (N)."""
    w = _lift(p, omega_v_rad_s)
    static = p.moving_mass_kg * p.g_m_s2 + p.platform_spring_n_per_m * p.preload_m
    swing = np.abs(p.platform_spring_n_per_m - p.moving_mass_kg * w * w) * p.eccentricity_m
    return np.asarray(static - swing), np.asarray(static + swing)


def follower_jump_rad_s(p: StructureParams) -> float:
    """Cam motor speed above which the roller leaves the cam at the top of the stroke (rad/s); inf when r_d = 0.

    F_c,min = 0 with M ω² > K_s: ω² = (M g + K_s (δ0 + r_d)) / (M r_d), ω = hω_v. Without springs this
    is Γ = 1: the platform's downward acceleration at the top of the stroke reaches g.
    """
    if p.eccentricity_m <= 0.0:
        return math.inf
    m = p.moving_mass_kg
    w2 = (m * p.g_m_s2 + p.platform_spring_n_per_m * (p.preload_m + p.eccentricity_m)) / (m * p.eccentricity_m)
    return math.sqrt(w2) / p.strokes


def cam_contact_pressure_pa(p: StructureParams, force_n: ArrayLike) -> FloatArray:
    """Hertz peak pressure of the cam–roller line contact, p_max = √(F E* / (π L R')) (Pa; eqs 21, 23 corrected)."""
    f = np.maximum(np.asarray(force_n, dtype=float), 0.0)
    return np.asarray(np.sqrt(f * p.contact_modulus_pa / (math.pi * p.contact_width_m * p.contact_radius_m)))


def cycles_to_fatigue(p: StructureParams, pressure_pa: ArrayLike) -> FloatArray:
    """Load cycles to contact fatigue at peak pressure p (inf at or below the endurance limit p_e).

    Above it N_e (p_e / p)^(20/3) (:data:`LINE_CONTACT_LIFE_EXPONENT`), N_e the cycles the limit is stated at.
    """
    pr = np.asarray(pressure_pa, dtype=float)
    with np.errstate(divide="ignore"):
        life = p.endurance_cycles * (p.endurance_pa / pr) ** LINE_CONTACT_LIFE_EXPONENT
    return np.asarray(np.where(pr <= p.endurance_pa, np.inf, life))


def shaft_load_peak_n(p: StructureParams, omega_r_rad_s: ArrayLike, omega_v_rad_s: ArrayLike) -> FloatArray:
    """Peak quasi-static load on the rotary shaft's bearings (N), the rods carried by the wall.

    (m_shaft + n m)(g + r_d (hω_v)²), plus the rods' unbalanced centripetal force: it cancels for n ≥ 2
    rods evenly spaced (Σ r̂_i = 0) and is m r0 ω_r² for one rod. Impacts are :func:`impact_force_n`.
    """
    w_r = np.asarray(omega_r_rad_s, dtype=float)
    unbalance = p.rod_mass_kg * p.r0_m * w_r * w_r if p.n_rods == 1 else 0.0 * w_r
    return np.asarray(p.shaft_mass_kg * (p.g_m_s2 + peak_platform_acceleration_m_s2(p, omega_v_rad_s)) + unbalance)


def bearing_life_h(p: StructureParams, load_n: ArrayLike, omega_r_rad_s: ArrayLike) -> FloatArray:
    """L10 life of one of the shaft's two bearings (hours): (C / P)³ × 10⁶ revolutions at ω_r, P = load/2."""
    load = np.maximum(0.5 * np.asarray(load_n, dtype=float), 1e-300)
    revs_per_h = np.asarray(omega_r_rad_s, dtype=float) / (2.0 * math.pi) * 3600.0
    with np.errstate(divide="ignore"):
        return np.asarray((p.bearing_rating_n / load) ** 3 * 1e6 / revs_per_h)


def line_contact_compliance_m_per_n(
    force_n: ArrayLike, length_m: float, radius1_m: float, radius2_m: float, modulus_pa: float
) -> FloatArray:
    """δ/F of two cylinders in line contact (m/N): (ln(8R₁/b) + ln(8R₂/b) − 1)/(π L E*), b the Hertz half-width.

    Johnson, Contact Mechanics (1985), ch. 5, two-dimensional contact of cylinders (the approach is
    logarithmic in R/b); b = 2√(F R'/(π L E*)), 1/R' = 1/R₁ + 1/R₂. Used for the rod on the bore with R₂ = r_v (the
    concave bore's log term taken as a cylinder's of the same radius: the logarithm's accuracy).
    """
    f = np.maximum(np.asarray(force_n, dtype=float), 1e-300)
    r_eff = 1.0 / (1.0 / radius1_m + 1.0 / radius2_m)
    b = 2.0 * np.sqrt(f * r_eff / (math.pi * length_m * modulus_pa))
    logs = np.log(8.0 * radius1_m / b) + np.log(8.0 * radius2_m / b) - 1.0
    return np.asarray(logs / (math.pi * length_m * modulus_pa))


def impact_force_n(
    energy_j: ArrayLike, length_m: float, radius1_m: float, radius2_m: float, modulus_pa: float
) -> FloatArray:
    """Peak force of an impact that dissipates ``energy_j`` in a line contact (N).

    The contact stores the energy E = ∫F dδ ≈ ½ F δ = ½ F² c(F), c the compliance
    (:func:`line_contact_compliance_m_per_n`, nearly constant: logarithmic in F), so F = √(2E / c(F)),
    solved by fixed-point iteration (the log changes by < 1e-9 after 8 steps). 0 where E ≤ 0.
    """
    e = np.maximum(np.asarray(energy_j, dtype=float), 0.0)
    force = np.sqrt(2.0 * e / line_contact_compliance_m_per_n(1.0, length_m, radius1_m, radius2_m, modulus_pa))
    for _ in range(8):
        c = line_contact_compliance_m_per_n(np.maximum(force, 1e-30), length_m, radius1_m, radius2_m, modulus_pa)
        force = np.sqrt(2.0 * e / c)
    return np.asarray(np.where(e > 0.0, force, 0.0))


def resting_contact_energy_j(
    weight_n: float, length_m: float, radius1_m: float, radius2_m: float, modulus_pa: float
) -> float:
    """Elastic energy the line contact stores under a resting load W, ½ W δ(W) (J).

    An impact that dissipates less than this never separates the contact by more than its own elastic
    approach under the rod's weight: it is the rod settling on the wall, not an impact on the powder.
    Studies count impacts above it (:data:`millctl.studies.metrics` ``impact threshold``).
    """
    c = float(line_contact_compliance_m_per_n(weight_n, length_m, radius1_m, radius2_m, modulus_pa))
    return 0.5 * weight_n * weight_n * c


__all__ = [
    "LINE_CONTACT_LIFE_EXPONENT",
    "StructureParams",
    "bearing_life_h",
    "cam_contact_force_n",
    "cam_contact_force_range_n",
    "cam_contact_pressure_pa",
    "cycles_to_fatigue",
    "follower_jump_rad_s",
    "impact_force_n",
    "line_contact_compliance_m_per_n",
    "peak_platform_acceleration_m_s2",
    "peak_spring_force_n",
    "platform_acceleration_m_s2",
    "resting_contact_energy_j",
    "shaft_load_peak_n",
    "spring_force_n",
]
