"""What a study can measure at a point, each metric at the cheapest level of detail that answers it.

Levels (docs/model.md#levels-of-detail-and-their-cost): (a) closed forms, (b)
the per-revolution summary, (c) the offline multi-rod simulation. A point
computes only the levels its metrics need.

Impact rates count every rod (eq. 18 corrected, n·p·ω_r/2π) in both variants,
so that the paper's and the corrected model compare like with like; the energy
of an impact is the variant's (eq. 19 printed, or ½ m_eff (1 − e²) v_n²).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from millctl.config.models import LimitLaw, MillConfig
from millctl.physics.cam import lift_phase_rad, lift_speed_rad_s
from millctl.physics.dose import dose_rate_j_g_s, milling_power_w, whole_mill_rate_hz
from millctl.physics.impact import hertz_half_width_m, spin_shear_pa
from millctl.physics.limits import LimitParams, omega_r_max, vibration_intensity
from millctl.physics.model import MillModel, Scene
from millctl.physics.simulate import simulate
from millctl.physics.telemetry import MIN_OMEGA_R_RAD_S, revolution_summary
from millctl.units import rad_s_to_rpm


@dataclass(frozen=True)
class Metric:
    """One metric: its name (with its unit), level of detail, and what it is."""

    name: str
    level: str
    """"a" closed form, "b" per-revolution summary, "c" multi-rod simulation."""
    description: str


def _margin_name(law: LimitLaw) -> str:
    return f"margin_{law.value.replace('-', '_')}_rpm"


_LIST = [
    *(Metric(_margin_name(law), "a", f"ω_r,max under {law.value} minus ω_r (rpm; < 0 outside)") for law in LimitLaw),
    Metric("gamma", "a", "cam intensity Γ = r_d (hω_v)²/g"),
    Metric("spring_force_amplitude_n", "a", "spring force amplitude k·r_d (N)"),
    Metric("paper_estimate_power_w", "a", "the paper's own estimate: eq. 18 with p = 1 × eq. 19 at |v| = r0 ω_r (W)"),
    Metric("rod_rod_shear_pa", "a", "eq. 20, μ W_r / A with the rod's whole weight on the line of centres (Pa)"),
    Metric("impact_rate_hz", "b", "impacts per second, whole mill, n·p·ω_r/2π (eq. 18 corrected)"),
    Metric("impact_rate_per_rod_hz", "b", "impacts per second and rod, p·ω_r/2π (eq. 18)"),
    Metric("impact_energy_mean_j", "b", "mean energy of an impact (eq. 19, variant's form) (J)"),
    Metric("milling_power_w", "b", "impact rate × mean impact energy (W)"),
    Metric("dose_rate_j_g_s", "b", "specific energy dose rate: milling power per gram of powder (J/g/s)"),
    Metric("wall_shear_pa", "b", "eq. 25, μ·p_av averaged over the pinned arc (Pa)"),
    Metric("detach_fraction", "b", "share of cam phases whose revolution has a detachment"),
    Metric("theta_d_deg", "b", "mean detachment angle (degrees; nan when pinned)"),
    Metric("impact_energy_p10_j", "c", "10th percentile of impact energy over the simulated impacts (J)"),
    Metric("impact_energy_p90_j", "c", "90th percentile of impact energy over the simulated impacts (J)"),
    Metric("sim_impact_rate_hz", "c", "impacts per second in the multi-rod simulation, whole mill"),
    Metric("spin_shear_pa", "c", "eq. 27 at the wall-impact points, mean of its magnitude (Pa)"),
]
METRICS: dict[str, Metric] = {m.name: m for m in _LIST}
"""Every metric by name."""

DEFAULT_METRICS = tuple(m.name for m in _LIST if m.level in ("a", "b"))
"""Metrics of a study that names none: every level-(a) and level-(b) metric."""


@dataclass(frozen=True)
class PointSettings:
    """How hard to look at one point."""

    cam_phases: int = 4
    revolutions: float = 4.0


def _level_a(config: MillConfig, model: MillModel, w_r: float, w_v: float) -> dict[str, float]:
    p = LimitParams.from_config(config)
    out = {_margin_name(law): float(rad_s_to_rpm(omega_r_max(law, p, w_v) - w_r)) for law in LimitLaw}
    out["gamma"] = float(vibration_intensity(p, w_v))
    out["spring_force_amplitude_n"] = model.spring_n_per_m * model.eccentricity_m
    # the paper's reasoning: one impact per revolution (eq. 18, p = 1) of ½ m |v|² at the wall speed (eq. 19)
    out["paper_estimate_power_w"] = w_r / (2.0 * math.pi) * 0.5 * model.rod_mass_kg * (model.r0_m * w_r) ** 2
    # eq. 20: two equal convex rods, 1/R' = 2/r_r, 1/E* = 2(1 − ν²)/E, W_r = m g
    weight = model.rod_mass_kg * model.g_m_s2
    r_eff = 0.5 * model.rod_radius_m
    e_star = model.rod_youngs_pa / (2.0 * (1.0 - model.rod_poisson**2))
    b = math.sqrt(4.0 * weight * r_eff / (math.pi * model.rod_length_m * e_star))
    out["rod_rod_shear_pa"] = model.powder_friction * weight / (2.0 * b * model.rod_length_m)
    return out


def _level_b(config: MillConfig, model: MillModel, w_r: float, w_v: float, cam_phases: int) -> dict[str, float]:
    s = revolution_summary(model, w_r, w_v, cam_phases=cam_phases)
    total = whole_mill_rate_hz(model.variant, model.n_rods, s.impact_rate_hz) if s.detached else 0.0
    return {
        "impact_rate_hz": total,
        "impact_rate_per_rod_hz": total / model.n_rods,
        "impact_energy_mean_j": s.mean_impact_energy_j if s.detached else math.nan,
        "milling_power_w": milling_power_w(model, s),
        "dose_rate_j_g_s": dose_rate_j_g_s(model, s, config.mill.powder.charge_g),
        "wall_shear_pa": s.mean_shear_pa,
        "detach_fraction": s.detach_fraction,
        "theta_d_deg": math.degrees(s.theta_d_rad),
    }


def _level_c(model: MillModel, w_r: float, w_v: float, revolutions: float, seed: int) -> tuple[dict[str, float], int]:
    """Metrics of the multi-rod simulation from seeded random phases, and its event count."""
    nan = math.nan
    if w_r < MIN_OMEGA_R_RAD_S:
        return {
            "impact_energy_p10_j": nan,
            "impact_energy_p90_j": nan,
            "sim_impact_rate_hz": 0.0,
            "spin_shear_pa": nan,
        }, 0
    theta0, alpha0 = np.random.default_rng(seed).uniform(0.0, 2.0 * math.pi, size=2)
    t_end = revolutions * 2.0 * math.pi / w_r
    result = simulate(Scene(model, w_r, w_v, float(theta0), float(alpha0)), t_end)
    energies = result.impacts["energy_j"]
    wall = result.impacts[result.impacts["partner"] == -1]
    spins = []
    for theta, alpha in zip(wall["theta_rad"], wall["alpha_rad"], strict=True):
        lift = lift_phase_rad(model.cam, float(alpha))
        g_eff = model.g_m_s2 - model.eccentricity_m * lift_speed_rad_s(model.cam, w_v) ** 2 * math.sin(lift)
        load = model.rod_mass_kg * max(model.r0_m * w_r * w_r - g_eff * math.sin(theta), 0.0)
        if hertz_half_width_m(model, load) > 0.0:
            spins.append(abs(spin_shear_pa(model, load, math.sin(lift), float(theta))))
    out = {
        "impact_energy_p10_j": float(np.percentile(energies, 10)) if energies.size else nan,
        "impact_energy_p90_j": float(np.percentile(energies, 90)) if energies.size else nan,
        "sim_impact_rate_hz": energies.size / t_end,
        "spin_shear_pa": float(np.mean(spins)) if spins else nan,
    }
    return out, int(result.impacts.size + result.detachments.size)


def compute_metrics(
    config: MillConfig, w_r: float, w_v: float, names: tuple[str, ...], settings: PointSettings, seed: int
) -> tuple[dict[str, float], int]:
    """The named metrics at speeds (rad/s) on a configured mill, and the number of events it took."""
    model = MillModel.from_config(config)
    levels = {METRICS[n].level for n in names}
    values: dict[str, float] = {}
    events = 0
    if "a" in levels:
        values.update(_level_a(config, model, w_r, w_v))
    if "b" in levels:
        values.update(_level_b(config, model, w_r, w_v, settings.cam_phases))
        events += settings.cam_phases
    if "c" in levels:
        sim, n_events = _level_c(model, w_r, w_v, settings.revolutions, seed)
        values.update(sim)
        events += n_events
    return {n: float(values[n]) for n in names}, events


__all__ = ["DEFAULT_METRICS", "METRICS", "Metric", "PointSettings", "compute_metrics"]
