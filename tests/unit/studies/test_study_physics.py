"""The physics of the studies: slip, the impact threshold, eqs 20 and 27 corrected, the cam-phase integral."""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

import numpy as np
import pytest

from millctl.cli import main
from millctl.config import MillConfig, ModelVariant
from millctl.physics import structure as st
from millctl.physics.model import MillModel
from millctl.physics.slip import traction_ratio
from millctl.physics.telemetry import revolution_summary
from millctl.studies.loads import impact_loads, impact_threshold_j, structural_violation_texts
from millctl.studies.metrics import PointSettings, cam_phase_summary, compute_metrics
from millctl.units import rad_s_to_rpm, rpm_to_rad_s
from tests.conftest import CONFIG_FILE, REPO


def corrected(config: MillConfig, **model: float) -> MillConfig:
    data = config.model_dump(mode="json")
    data["model"] = {**data["model"], "variant": "corrected", **model}
    return MillConfig.model_validate(data)


def metrics(config: MillConfig, rot_rpm: float, vib_rpm: float, *names: str, **settings: Any) -> dict[str, float]:
    values, _ = compute_metrics(
        config, rpm_to_rad_s(rot_rpm), rpm_to_rad_s(vib_rpm), names, PointSettings(**settings), 1
    )
    return values


def test_slip_fraction_is_the_reference_engines_no_slip_check(config: MillConfig) -> None:
    model = MillModel.from_config(corrected(config))
    w_r, w_v = rpm_to_rad_s(200.0), rpm_to_rad_s(800.0)
    compiled = revolution_summary(model, w_r, w_v, cam_phases=8)
    reference = revolution_summary(model, w_r, w_v, cam_phases=8, engine="reference")
    assert compiled.slip_fraction == reference.slip_fraction
    assert compiled.slip_fraction > 0.0 and compiled.no_slip_violated


def test_slip_fraction_follows_the_friction_a_pinned_rod_needs(config: MillConfig) -> None:
    """A rod pinned at 300/400 rpm slips where the largest |F_t|/N of its carriage exceeds μ, and only there."""
    model = MillModel.from_config(corrected(config))
    w_r, w_v = rpm_to_rad_s(300.0), rpm_to_rad_s(400.0)
    theta, alpha = np.meshgrid(np.linspace(-math.pi, math.pi, 721), np.linspace(0.0, 2 * math.pi, 721))
    needed = float(traction_ratio(model, w_r, w_v, theta, alpha).max())
    for mu in (0.8 * needed, 1.2 * needed):
        values = metrics(corrected(config, powder_friction=mu), 300.0, 400.0, "slip_fraction", "detach_fraction")
        assert values["detach_fraction"] == 0.0  # pinned: only the carriage can fail
        assert (values["slip_fraction"] > 0.0) == (mu < needed)


def test_micro_hops_are_not_counted_as_impacts(config: MillConfig) -> None:
    cfg = corrected(config)
    model = MillModel.from_config(cfg)
    threshold = impact_threshold_j(model)
    every = revolution_summary(model, rpm_to_rad_s(3.0), rpm_to_rad_s(800.0), cam_phases=16)
    assert every.detached and every.mean_impact_energy_j < threshold  # the landings of 3 rpm are micro-hops
    values = metrics(cfg, 3.0, 800.0, "detach_fraction", "micro_hop_fraction", "milling_power_w", "impact_rate_hz")
    assert values["micro_hop_fraction"] == 1.0
    assert values["detach_fraction"] == 0.0 and values["milling_power_w"] == 0.0 and values["impact_rate_hz"] == 0.0
    # well above the threshold nothing is dropped
    assert metrics(cfg, 100.0, 800.0, "micro_hop_fraction")["micro_hop_fraction"] == 0.0


def test_the_threshold_is_the_resting_contacts_elastic_energy(config: MillConfig) -> None:
    model = MillModel.from_config(config)
    weight = model.rod_mass_kg * model.g_m_s2
    e_star = 1.0 / (2 * (1 - model.rod_poisson**2) / model.rod_youngs_pa)
    expected = st.resting_contact_energy_j(weight, model.rod_length_m, model.rod_radius_m, model.vial_radius_m, e_star)
    assert impact_threshold_j(model) == pytest.approx(expected, rel=1e-12)


def test_spin_shear_is_eq27_corrected_and_free_of_the_spring_term(config: MillConfig) -> None:
    """Printed eq. 27 is k r_d sin α cos θ/(2 L b): ∝ k. The corrected traction shear does not involve k."""
    soft, stiff = corrected(config), corrected(config)
    stiff = MillConfig.model_validate(
        {
            **stiff.model_dump(mode="json"),
            "mill": {**stiff.model_dump(mode="json")["mill"], "spring": {"stiffness_n_per_m": 920.0}},
        }
    )
    a = metrics(soft, 100.0, 800.0, "spin_shear_pa", revolutions=1.0)["spin_shear_pa"]
    b = metrics(stiff, 100.0, 800.0, "spin_shear_pa", revolutions=1.0)["spin_shear_pa"]
    assert math.isfinite(a) and a > 0.0
    assert a == b


def test_eq20_takes_the_impact_force(config: MillConfig) -> None:
    cfg = corrected(config)
    model = MillModel.from_config(cfg)
    values = metrics(cfg, 150.0, 800.0, "impact_energy_mean_j", "impact_force_peak_n", "rod_rod_shear_pa")
    energy = values["impact_energy_mean_j"]
    e_wall = 1.0 / (2 * (1 - model.rod_poisson**2) / model.rod_youngs_pa)
    force = float(st.impact_force_n(energy, model.rod_length_m, model.rod_radius_m, model.vial_radius_m, e_wall))
    assert values["impact_force_peak_n"] == pytest.approx(force, rel=1e-12)
    e_rods = model.rod_youngs_pa / (2 * (1 - model.rod_poisson**2))
    b = math.sqrt(4 * force * 0.5 * model.rod_radius_m / (math.pi * model.rod_length_m * e_rods))
    assert values["rod_rod_shear_pa"] == pytest.approx(model.powder_friction * force / (2 * b * model.rod_length_m))
    weight = model.rod_mass_kg * model.g_m_s2
    assert force > 100.0 * weight  # the weight (eq. 20 as printed) understates the load by orders of magnitude
    assert float(impact_loads(model, 0.0)["rod_rod_shear_pa"]) == 0.0


def test_the_cam_phase_integral_meets_its_stated_error(config: MillConfig) -> None:
    model = MillModel.from_config(corrected(config))
    w_r, w_v = rpm_to_rad_s(150.0), rpm_to_rad_s(800.0)
    rtol = 0.01
    summary, used, error = cam_phase_summary(model, w_r, w_v, PointSettings(cam_phase_rtol=rtol), 0.0)
    assert 16 <= used <= 256 and (error <= rtol or used == 256)
    fine = revolution_summary(model, w_r, w_v, cam_phases=1024)
    assert summary.impact_power_w == pytest.approx(fine.impact_power_w, rel=3 * rtol)
    four = revolution_summary(model, w_r, w_v, cam_phases=4)  # the old fixed sample, for scale
    assert abs(four.impact_power_w - fine.impact_power_w) > abs(summary.impact_power_w - fine.impact_power_w)


def test_recipe_plan_names_per_rod_and_whole_mill_rates(config: MillConfig, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--config", str(CONFIG_FILE), "recipe", "plan", "--json", str(REPO / "config/recipes/demo.toml")]) == 0
    data = json.loads(capsys.readouterr().out)["result"]
    model = MillModel.from_config(config)
    hold = next(s for s in data["steps"] if s["kind"] == "hold" and s["detached"])
    summary = revolution_summary(model, rpm_to_rad_s(hold["rotary_rpm"]), rpm_to_rad_s(hold["vibration_rpm"]))
    # the paper variant reports eq. 18 per rod; the whole mill has n times that, and the dose uses the mill's
    assert model.variant is ModelVariant.PAPER
    assert hold["impact_rate_per_rod_hz"] == pytest.approx(summary.impact_rate_hz)
    assert hold["impact_rate_mill_hz"] == pytest.approx(model.n_rods * summary.impact_rate_hz)
    dose_j_g = (
        hold["impact_rate_mill_hz"] * hold["impact_energy_mj"] * 1e-3 * hold["duration_s"] / data["powder_charge_g"]
    )
    assert hold["dose_kj_g"] == pytest.approx(dose_j_g * 1e-3, rel=1e-9)
    assert "impact_rate_hz" not in hold


def test_slip_metrics_with_the_slip_ride(config: MillConfig) -> None:
    cfg = corrected(config)
    names = ("milling_power_w", "slip_milling_power_w", "slip_impact_fraction", "slip_impact_energy_mean_j",
             "slip_unresolved_fraction")  # fmt: skip
    values = metrics(cfg, 200.0, 800.0, *names, slip_phases=4)
    # with μ = 0.3 the sliding rod delivers far less than the no-slip carriage (docs/model.md, slip)
    assert 0.0 <= values["slip_milling_power_w"] < 0.1 * values["milling_power_w"]
    assert 0.0 <= values["slip_impact_fraction"] <= 1.0 and values["slip_unresolved_fraction"] == 0.0
    if values["slip_impact_fraction"] > 0.0:
        model = dataclasses.replace(MillModel.from_config(cfg))
        rate = model.n_rods * values["slip_impact_fraction"] * rpm_to_rad_s(200.0) / (2 * math.pi)
        assert values["slip_milling_power_w"] == pytest.approx(rate * values["slip_impact_energy_mean_j"])


def test_the_multi_rod_simulation_says_where_its_carriage_slips(config: MillConfig) -> None:
    """Level (c): every carried arc that ends in a departure slips before it (|F_t|/N → ∞ as N → 0); the
    arc over which it does shrinks as the wall's grip μ grows."""
    leads = []
    for mu in (0.3, 1.0, 2.0):
        values = metrics(
            corrected(config, powder_friction=mu), 200.0, 800.0, "sim_slip_fraction", "sim_slip_lead_deg",
            revolutions=2.0,
        )  # fmt: skip
        assert values["sim_slip_fraction"] == 1.0
        leads.append(values["sim_slip_lead_deg"])
    assert 0.0 < leads[2] < leads[1] < leads[0] < 360.0


def test_the_multi_rod_simulation_with_the_slip_ride(config: MillConfig) -> None:
    """Level (c) run again with the held rods' slip ride: at μ = 0.3 most departures follow a slide, and the
    rods that slide back down the wall deliver a fraction of the carried rods' power (200/800 rpm)."""
    names = ("sim_power_w", "slip_sim_power_w", "slip_sim_impact_rate_hz", "slip_sim_slid_fraction",
             "slip_sim_slide_time_s", "slip_sim_overlap_share")  # fmt: skip
    values = metrics(corrected(config), 200.0, 800.0, *names, revolutions=2.0)
    assert 0.3 < values["slip_sim_slid_fraction"] <= 1.0
    assert 0.5 < values["slip_sim_overlap_share"] <= 1.0  # the six rods slide into one heap (not modelled)
    assert 0.0 < values["slip_sim_slide_time_s"] < 2.0 * 60.0 / 200.0
    assert 0.0 < values["slip_sim_power_w"] < 0.5 * values["sim_power_w"]
    carried = metrics(corrected(config), 200.0, 800.0, "sim_power_w", revolutions=2.0)
    assert carried["sim_power_w"] == values["sim_power_w"]  # the carried run is the same run either way
    counted = values["slip_sim_impact_rate_hz"] * 2.0 * 60.0 / 200.0  # impacts over the two revolutions
    assert counted >= 1.0 and counted == pytest.approx(round(counted))


def test_structural_constraints_name_value_and_bound_per_point(config: MillConfig) -> None:
    jump_rpm = rad_s_to_rpm(st.follower_jump_rad_s(st.StructureParams.from_config(config)))
    speeds = np.array([0.9 * jump_rpm, 1.1 * jump_rpm])
    texts = structural_violation_texts(config, speeds, cam_contact=True, contact_fatigue=True)
    assert 0 not in texts and len(texts[1]) == 1 and "roller leaves the cam" in texts[1][0]
    assert f"{jump_rpm:.1f} rpm" in texts[1][0]
    data = config.model_dump(mode="json")
    data["mill"]["structure"] = {"contact_endurance_mpa": 100.0}  # below the static contact's own pressure
    weak = MillConfig.model_validate(data)
    texts = structural_violation_texts(weak, speeds, cam_contact=False, contact_fatigue=True)
    assert sorted(texts) == [0, 1] and all(len(t) == 1 and "> endurance limit 100 MPa" in t[0] for t in texts.values())
    assert structural_violation_texts(weak, speeds, cam_contact=False, contact_fatigue=False) == {}
