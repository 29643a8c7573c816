"""The numbers of docs/model.md's errata table, computed (``python -m millctl.physics.errata``).

Nothing in the errata table is typed by hand: this module prints every figure the
new and corrected rows quote, for the configured mill (Set A by default), and the
slip comparison at the paper's operating point (:mod:`millctl.physics.slip_ride`).

* eq. 7: θ_d over the cam phase (:func:`theta_d_over_cam_phase`): the rod is carried
  up from the bottom (θ0 = −π/2) and the cam phase α0 it has there is uniform over
  [0, 2π) (K midpoints); the mean is the arithmetic mean of θ_d over the K phases.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from millctl.config import MillConfig, ModelVariant, load_config
from millctl.physics import structure
from millctl.physics.detachment import find_detachment
from millctl.physics.impact import (
    carriage_shear_pa,
    effective_modulus_pa,
    hertz_half_width_m,
    rod_rod_contact_area_m2,
    rod_rod_weight_shear_pa,
    spin_shear_pa,
)
from millctl.physics.legacy import arc_wall_sink_leading_m, arc_wall_sink_m
from millctl.physics.limits import LimitParams, eq9_vacuous_below_rad_s
from millctl.physics.model import MillModel, Scene
from millctl.physics.simulate import simulate
from millctl.physics.telemetry import revolution_summary
from millctl.units import rad_s_to_rpm, rpm_to_rad_s


@dataclass(frozen=True)
class CamPhaseSpread:
    """θ_d of a rod carried up from the bottom, over a uniform cam phase there (eq. 7 row)."""

    phases: int
    detached_fraction: float
    mean_deg: float
    """Arithmetic mean of θ_d over the detaching phases (deg)."""
    circular_mean_deg: float
    min_deg: float
    max_deg: float


def theta_d_over_cam_phase(
    model: MillModel, omega_r_rad_s: float, omega_v_rad_s: float, phases: int = 3600
) -> CamPhaseSpread:
    """θ_d for α0 = 2π(k + ½)/K, k < K, with the rod at the bottom at t = 0 (``find_detachment``)."""
    thetas = []
    for k in range(phases):
        det = find_detachment(
            Scene(model, omega_r_rad_s, omega_v_rad_s, -0.5 * math.pi, 2 * math.pi * (k + 0.5) / phases)
        )
        if det.detached:
            thetas.append(det.theta_rad)
    if not thetas:
        return CamPhaseSpread(phases, 0.0, math.nan, math.nan, math.nan, math.nan)
    th = np.asarray(thetas)
    circ = math.atan2(float(np.sin(th).sum()), float(np.cos(th).sum()))
    deg = np.degrees(th)
    return CamPhaseSpread(
        phases, len(thetas) / phases, float(deg.mean()), math.degrees(circ), float(deg.min()), float(deg.max())
    )


def errata_numbers(model: MillModel, omega_r_rpm: float = 200.0, omega_v_rpm: float = 800.0) -> dict[str, Any]:
    """Every figure the errata rows quote, for ``model`` at the given operating point."""
    corrected = dataclasses.replace(model, variant=ModelVariant.CORRECTED)
    paper = dataclasses.replace(model, variant=ModelVariant.PAPER)
    w_r, w_v = rpm_to_rad_s(omega_r_rpm), rpm_to_rad_s(omega_v_rpm)
    m = model.rod_mass_kg
    spread = theta_d_over_cam_phase(corrected, w_r, w_v)
    four = revolution_summary(corrected, w_r, w_v, cam_phases=4)
    quarter = [find_detachment(Scene(corrected, w_r, w_v, -0.5 * math.pi, 0.5 * math.pi * k)) for k in range(4)]
    sim_means = []  # the n-rod simulation over 3 s, from three starting cam phases
    for alpha0 in (0.0, 1.0, 2.0):
        run = simulate(Scene(corrected, w_r, w_v, -0.5 * math.pi, alpha0), 3.0)
        if len(run.detachments):
            sim_means.append(float(np.degrees(run.detachments["theta_rad"]).mean()))
    n_top = m * model.r0_m * w_r * w_r  # θ = 0: N = m r0 ω_r², the paper's N_c
    uncapped, capped = carriage_shear_pa(corrected, w_r, w_v, 0.0, 0.0)
    weight = m * model.g_m_s2
    params = LimitParams(m, model.r0_m, model.eccentricity_m, 1e5, model.g_m_s2)
    return {
        "operating_point_rpm": [omega_r_rpm, omega_v_rpm],
        "eq7_theta_d_cam_phase": dataclasses.asdict(spread),
        "eq7_theta_d_telemetry_4_phases_deg": math.degrees(four.theta_d_rad),
        "eq7_theta_d_4_phases_from_bottom_deg": float(np.mean([math.degrees(d.theta_rad) for d in quarter])),
        "eq7_theta_d_simulation_3s_deg_range": [min(sim_means), max(sim_means)] if sim_means else [],
        "eq15_17_sink_q360_um": arc_wall_sink_m(model, 360) * 1e6,
        "eq15_17_sink_leading_q360_um": arc_wall_sink_leading_m(model, 360) * 1e6,
        "eq15_17_old_sagitta_q360_um": (math.pi * model.vial_radius_m / 360) ** 2 / (2 * model.rod_radius_m) * 1e6,
        "eq26_27_normal_force_top_n": n_top,
        "eq26_27_paper_eq27_mpa": spin_shear_pa(paper, n_top, 1.0, 0.0) / 1e6,
        "eq26_27_paper_form_corrected_b_mpa": spin_shear_pa(corrected, n_top, 1.0, 0.0) / 1e6,
        "eq26_27_traction_uncapped_mpa": uncapped / 1e6,
        "eq26_27_traction_capped_mpa": capped / 1e6,
        "eq26_27_half_width_um": hertz_half_width_m(corrected, n_top) * 1e6,
        "eq20_weight_n": weight,
        "eq20_area_mm2": rod_rod_contact_area_m2(model, weight) * 1e6,
        "eq20_half_width_um": rod_rod_contact_area_m2(model, weight) / (2 * model.rod_length_m) * 1e6,
        "eq20_shear_mpa": rod_rod_weight_shear_pa(model, weight) / 1e6,
        "k_vacuous_below_rpm_at_1e5": float(rad_s_to_rpm(eq9_vacuous_below_rad_s(params))),
        "k_spring_force_n": model.spring_n_per_m * model.eccentricity_m,
        "k_weight_n": weight,
    }


def structural_numbers(config: MillConfig, omega_r_rpm: float = 200.0, omega_v_rpm: float = 800.0) -> dict[str, Any]:
    """The figures docs/model.md#structural-loads quotes, for a configured mill at the operating point."""
    p = structure.StructureParams.from_config(config)
    model = dataclasses.replace(MillModel.from_config(config), variant=ModelVariant.CORRECTED)
    w_r, w_v = rpm_to_rad_s(omega_r_rpm), rpm_to_rad_s(omega_v_rpm)
    low, high = (float(x) for x in structure.cam_contact_force_range_n(p, w_v))
    bare = dataclasses.replace(p, platform_spring_n_per_m=0.0, preload_m=0.0)
    shaft = float(structure.shaft_load_peak_n(p, w_r, w_v))
    weight = model.rod_mass_kg * model.g_m_s2
    wall = (model.rod_length_m, model.rod_radius_m, model.vial_radius_m, effective_modulus_pa(model))
    energy = revolution_summary(model, w_r, w_v, cam_phases=16).mean_impact_energy_j
    return {
        "moving_mass_kg": p.moving_mass_kg,
        "follower_jump_rpm": float(rad_s_to_rpm(structure.follower_jump_rad_s(p))),
        "follower_jump_without_springs_rpm": float(rad_s_to_rpm(structure.follower_jump_rad_s(bare))),
        "cam_contact_force_range_n": [low, high],
        "cam_contact_pressure_mpa": float(structure.cam_contact_pressure_pa(p, high)) / 1e6,
        "contact_endurance_mpa": p.endurance_pa / 1e6,
        "shaft_load_peak_n": shaft,
        "bearing_life_h": float(structure.bearing_life_h(p, shaft, w_r)),
        "impact_threshold_j": structure.resting_contact_energy_j(weight, *wall),
        "resting_approach_nm": float(structure.line_contact_compliance_m_per_n(weight, *wall)) * weight * 1e9,
        "impact_energy_mean_16_phases_j": energy,
        "impact_force_n": float(structure.impact_force_n(energy, *wall)),
        "weight_n": weight,
    }


def _cell(value: float, spec: str) -> str:
    return "—" if math.isnan(value) else format(value, spec)


def _emit(text: str) -> None:
    sys.stdout.write(text + "\n")


def main(argv: list[str] | None = None) -> int:
    """Print the errata numbers (and the slip comparison) for the configured mill."""
    from millctl.physics.slip_ride import slip_effect

    parser = argparse.ArgumentParser(prog="python -m millctl.physics.errata", description=__doc__)
    parser.add_argument("--config", help="mill configuration (default: the one in force)")
    parser.add_argument("--rot-rpm", type=float, default=200.0)
    parser.add_argument("--vib-rpm", type=float, default=800.0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    config = load_config(args.config).config
    model = MillModel.from_config(config)
    numbers = errata_numbers(model, args.rot_rpm, args.vib_rpm)
    numbers["structure"] = structural_numbers(config, args.rot_rpm, args.vib_rpm)
    w_r, w_v = rpm_to_rad_s(args.rot_rpm), rpm_to_rad_s(args.vib_rpm)
    effects = [slip_effect(model, w_r, w_v, friction=mu) for mu in (None, 1.0, 3.0)]
    if args.json:
        _emit(json.dumps({"errata": numbers, "slip": effects}, indent=2, default=float))
        return 0
    for key, value in numbers.items():
        _emit(f"{key}: {value}")
    for effect in effects:
        _emit("")
        _emit(f"μ = {effect['friction']:g}, {effect['phases']} cam phases, one rod from the bottom, one revolution:")
        _emit("")
        _emit("| model | detaching phases | θ_d (°) | flight (ms) | wall impact (mJ) | sliding before (ms) |")
        _emit("|---|---|---|---|---|---|")
        for r in effect["rows"]:
            cells = [_cell(r["theta_d_deg"], ".1f"), _cell(r["flight_ms"], ".2f"), _cell(r["energy_mj"], ".3f")]
            _emit(
                f"| {r['model']} | {r['detach_fraction']:.0%} | {' | '.join(cells)} | {_cell(r['sliding_ms'], '.1f')} |"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
