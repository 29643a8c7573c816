"""Structural, slip and threshold metrics of a study, as vectorised functions of arrays of points.

* :func:`structural_metrics` (level a): the loads of :mod:`millctl.physics.structure` at arrays
  of (ω_r, ω_v) for one mill; every entry an array of the points' shape;
* :func:`structural_violations`: the structural constraints, in physical terms (the roller stays
  on the cam; the cam contact stays below its endurance limit), each saying value and bound;
* :func:`impact_threshold_j`: the energy below which a landing is not an impact (a micro-hop);
* :func:`impact_loads` (level b): the impact force of eq. 20 and the rod–rod shear it makes;
* :func:`slip_ride_metrics` (level s): rod 0 ridden with Coulomb friction over K cam phases
  (:mod:`millctl.physics.slip_ride`), its wall impacts above the threshold;
* :func:`carried_arc_slip` (level c): where the multi-rod simulation's no-slip carriage fails.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from millctl.config.models import MillConfig, ModelVariant
from millctl.physics import structure as st
from millctl.physics.impact import effective_modulus_pa
from millctl.physics.model import MillModel, Scene
from millctl.physics.slip import no_slip_check
from millctl.physics.slip_ride import fly_to_wall, ride
from millctl.units import rad_s_to_rpm

FloatArray = NDArray[np.float64]


def structural_metrics(config: MillConfig, omega_r_rad_s: ArrayLike, omega_v_rad_s: ArrayLike) -> dict[str, FloatArray]:
    """Level-(a) structural loads at arrays of speeds (rad/s), broadcast together (docs/model.md#structural-loads)."""
    p = st.StructureParams.from_config(config)
    w_r, w_v = np.broadcast_arrays(np.asarray(omega_r_rad_s, dtype=float), np.asarray(omega_v_rad_s, dtype=float))
    f_min, f_max = st.cam_contact_force_range_n(p, w_v)
    pressure = st.cam_contact_pressure_pa(p, f_max)
    shaft = st.shaft_load_peak_n(p, w_r, w_v)
    jump_rpm = float(rad_s_to_rpm(st.follower_jump_rad_s(p)))
    return {
        "platform_acceleration_peak_m_s2": st.peak_platform_acceleration_m_s2(p, w_v),
        "spring_force_peak_n": np.full(w_v.shape, st.peak_spring_force_n(p)),
        "cam_contact_force_min_n": f_min,
        "cam_contact_force_max_n": f_max,
        "follower_jump_margin_rpm": jump_rpm - np.asarray(rad_s_to_rpm(w_v)),
        "cam_contact_pressure_pa": pressure,
        "cam_fatigue_cycles": st.cycles_to_fatigue(p, pressure),
        "shaft_load_peak_n": shaft,
        "bearing_life_h": st.bearing_life_h(p, shaft, w_r),
    }


def structural_violation_texts(
    config: MillConfig, omega_v_rpm: ArrayLike, cam_contact: bool, contact_fatigue: bool
) -> dict[int, list[str]]:
    """The structural constraints broken at each cam speed of an array (rpm): the texts of each point that breaks one.

    Vectorised over the points (the array engine's form), keyed by the point's index (a point that breaks none
    has no entry); each text says the value, the bound and where to read more.
    """
    p = st.StructureParams.from_config(config)
    w_v_rpm = np.atleast_1d(np.asarray(omega_v_rpm, dtype=float))
    f_min, f_max = st.cam_contact_force_range_n(p, w_v_rpm * math.pi / 30.0)
    pressure = st.cam_contact_pressure_pa(p, f_max)
    jump = float(rad_s_to_rpm(st.follower_jump_rad_s(p)))
    found: dict[int, list[str]] = {}
    for i in np.flatnonzero(f_min < 0.0).tolist() if cam_contact else ():
        found.setdefault(i, []).append(
            f"cam contact force min {float(f_min[i]):.3g} N < 0 at ω_v = {float(w_v_rpm[i]):.0f} rpm: the roller "
            f"leaves the cam above {jump:.1f} rpm (docs/model.md#structural-loads)"
        )
    for i in np.flatnonzero(pressure > p.endurance_pa).tolist() if contact_fatigue else ():
        found.setdefault(i, []).append(
            f"cam contact pressure {float(pressure[i]) / 1e6:.4g} MPa > endurance limit {p.endurance_pa / 1e6:g} MPa "
            f"at ω_v = {float(w_v_rpm[i]):.0f} rpm (docs/model.md#structural-loads)"
        )
    return found


def structural_violations(
    config: MillConfig, omega_v_rpm: float, cam_contact: bool, contact_fatigue: bool
) -> list[str]:
    """The structural constraints one cam speed (rpm) breaks (:func:`structural_violation_texts` of one point)."""
    return structural_violation_texts(config, omega_v_rpm, cam_contact, contact_fatigue).get(0, [])


def _rod_wall(model: MillModel) -> tuple[float, float, float, float]:
    corrected = dataclasses.replace(model, variant=ModelVariant.CORRECTED)
    return model.rod_length_m, model.rod_radius_m, model.vial_radius_m, effective_modulus_pa(corrected)


def impact_threshold_j(model: MillModel) -> float:
    """Energy below which a landing is not counted as an impact: ½ W δ(W) of the rod resting on the wall (J).

    W = m g; δ(W) the elastic approach of the rod–bore line contact under it
    (:func:`millctl.physics.structure.resting_contact_energy_j`). Set A: 2.5e-10 J, against 3e-18 J
    micro-hops and 3e-6 J impacts of the slipping rod.
    """
    return st.resting_contact_energy_j(model.rod_mass_kg * model.g_m_s2, *_rod_wall(model))


def impact_loads(model: MillModel, mean_energy_j: ArrayLike) -> dict[str, FloatArray]:
    """Eq. 20 with the impact force: the peak wall-impact force and the rod–rod shear μ F/A(F) (vectorised).

    F from :func:`millctl.physics.structure.impact_force_n` at the mean impact energy (wall contact,
    R₁ = r_r, R₂ = r_v); the rod–rod shear puts the same force on the strip A = 2 b L of two equal
    rods (R' = r_r/2, 1/E* = 2(1 − ν²)/E), τ = μ F / A (docs/model.md errata, eq. 20).
    """
    energy = np.nan_to_num(np.asarray(mean_energy_j, dtype=float), nan=0.0)
    force = st.impact_force_n(energy, *_rod_wall(model))
    e_star = model.rod_youngs_pa / (2.0 * (1.0 - model.rod_poisson**2))
    b = np.sqrt(4.0 * force * (0.5 * model.rod_radius_m) / (math.pi * model.rod_length_m * e_star))
    area = 2.0 * b * model.rod_length_m
    with np.errstate(divide="ignore", invalid="ignore"):
        shear = np.where(area > 0.0, model.powder_friction * force / np.where(area > 0.0, area, 1.0), 0.0)
    return {"impact_force_peak_n": force, "rod_rod_shear_pa": np.asarray(shear)}


def slip_ride_metrics(
    model: MillModel, omega_r_rad_s: float, omega_v_rad_s: float, phases: int, threshold_j: float
) -> tuple[dict[str, float], int]:
    """Rod 0 carried from the bottom with Coulomb friction (spin locked), K cam phases, one revolution.

    The ride is the corrected mechanics in both variants (the paper's eq. 7 cannot describe a
    sliding rod). Per phase: detaches? lands on the wall? with what energy (½ m (1 − e²) v_n²)?
    Landings below ``threshold_j`` are not impacts. Returns the share of phases with an impact
    (each one impact per rod and revolution at most), their mean energy, the whole mill's power, and
    the share of phases whose landing the contact search could not bracket (``slip_unresolved_fraction``:
    :func:`~millctl.physics.slip_ride.fly_to_wall` raises there; those phases count as no impact).
    """
    nan = math.nan
    energies: list[float] = []
    events = unresolved = 0
    lift_cycle = 2.0 * math.pi / (2 if model.cam.value == "double" else 1)
    for k in range(phases):
        scene = Scene(model, omega_r_rad_s, omega_v_rad_s, -0.5 * math.pi, lift_cycle * (k + 0.5) / phases)
        r = ride(scene, "locked")
        events += 1
        if not r.detached:
            continue
        events += 1
        try:
            landing = fly_to_wall(scene, r.time_s, r.theta_rad, r.theta_rate_rad_s)
        except ValueError:  # the contact root finder's bracket fails after a sliding departure: counted, not hidden
            unresolved += 1
            continue
        if landing is not None and landing.energy_j >= threshold_j:
            energies.append(landing.energy_j)
    fraction = len(energies) / phases
    mean = float(np.mean(energies)) if energies else nan
    rate = model.n_rods * fraction * omega_r_rad_s / (2.0 * math.pi)
    return {
        "slip_impact_fraction": fraction,
        "slip_impact_energy_mean_j": mean,
        "slip_milling_power_w": rate * mean if energies else 0.0,
        "slip_unresolved_fraction": unresolved / phases,
    }, events


def carried_arc_slip(scene: Scene, impacts: NDArray[np.void], detachments: NDArray[np.void]) -> tuple[float, float]:
    """Slip along the carried arcs of a multi-rod simulation (level c): (share that slip, mean lead in deg).

    Each departure ends an arc on which the rod was carried from its last landing (or from t = 0):
    :func:`~millctl.physics.slip.no_slip_check` says whether, and from when, that carriage needs
    |F_t| > μN. The lead is the wall angle ω_r (t_d − t_onset) over which the no-slip picture is
    wrong before the rod leaves (0 where it holds). (nan, nan) without departures.
    """
    w_r = scene.omega_r_rad_s
    slipped, leads = 0, []
    for t_d, rod in zip(detachments["time_s"], detachments["rod"], strict=True):
        before = impacts[(impacts["rod"] == rod) & (impacts["time_s"] < t_d)]
        if before.size:
            last = before[np.argmax(before["time_s"])]
            t_0, theta_0 = float(last["time_s"]), float(last["theta_rad"])
        else:
            t_0, theta_0 = 0.0, scene.rod_theta0_rad(int(rod))
        check = no_slip_check(scene, theta0_rad=theta_0 - w_r * t_0, t_start_s=t_0, arc_end_s=float(t_d))
        slipped += check.violated
        leads.append(math.degrees(w_r * (float(t_d) - check.onset_time_s)) if check.violated else 0.0)
    if not leads:
        return math.nan, math.nan
    return slipped / len(leads), float(np.mean(leads))


__all__ = [
    "carried_arc_slip",
    "impact_loads",
    "impact_threshold_j",
    "slip_ride_metrics",
    "structural_metrics",
    "structural_violation_texts",
    "structural_violations",
]
