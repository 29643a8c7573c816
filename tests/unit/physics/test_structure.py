"""The structural-load model (millctl.physics.structure): limits, units and hand-checkable cases."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from millctl.config import MillConfig
from millctl.physics import structure as st

G = 9.80665


@pytest.fixture
def params(config: MillConfig) -> st.StructureParams:
    return st.StructureParams.from_config(config)


def test_set_a_structure_from_the_configuration(params: st.StructureParams, config: MillConfig) -> None:
    s = config.mill.structure
    rods = config.mill.rods.count * config.rod_mass_kg
    assert params.moving_mass_kg == pytest.approx(s.platform_mass_kg + rods)
    assert params.shaft_mass_kg == pytest.approx(s.shaft_mass_kg + rods)
    # 1/R' = 1/R_roller + 1/R_cam, both convex (mm → m)
    assert params.contact_radius_m == pytest.approx(1e-3 / (1 / s.roller_radius_mm + 1 / s.cam_radius_mm))


def test_cam_contact_force_over_the_phase_has_the_closed_form_range(params: st.StructureParams) -> None:
    alpha = np.linspace(0.0, 2.0 * math.pi, 20_001)
    for rpm in (200.0, 800.0, 1200.0):
        w = rpm * math.pi / 30.0
        force = st.cam_contact_force_n(params, w, alpha)
        lo, hi = st.cam_contact_force_range_n(params, w)
        assert force.min() == pytest.approx(float(lo), rel=1e-9, abs=1e-9)
        assert force.max() == pytest.approx(float(hi), rel=1e-9)
        # Newton on the platform: F_c − M g − K_s(δ0 + y) = M ÿ
        y = params.eccentricity_m * np.sin(alpha)
        lhs = force - params.moving_mass_kg * G - params.platform_spring_n_per_m * (params.preload_m + y)
        accel = st.platform_acceleration_m_s2(params, w, alpha)
        np.testing.assert_allclose(lhs, params.moving_mass_kg * accel, atol=1e-9)


def test_without_springs_the_roller_jumps_where_the_platform_accelerates_at_g(params: st.StructureParams) -> None:
    bare = dataclasses.replace(params, platform_spring_n_per_m=0.0, preload_m=0.0)
    jump = st.follower_jump_rad_s(bare)
    assert jump == pytest.approx(math.sqrt(G / bare.eccentricity_m))  # Γ = r_d ω²/g = 1
    assert float(st.peak_platform_acceleration_m_s2(bare, jump)) == pytest.approx(G)
    assert float(st.cam_contact_force_range_n(bare, jump)[0]) == pytest.approx(0.0, abs=1e-9)
    # with the configured springs the contact force at the jump speed is zero too, and negative above
    w = st.follower_jump_rad_s(params)
    assert float(st.cam_contact_force_range_n(params, w)[0]) == pytest.approx(0.0, abs=1e-9)
    assert (
        float(st.cam_contact_force_range_n(params, 1.01 * w)[0])
        < 0.0
        < float(st.cam_contact_force_range_n(params, 0.99 * w)[0])
    )
    assert st.follower_jump_rad_s(dataclasses.replace(params, eccentricity_m=0.0)) == math.inf
    # a double-acting cam strokes twice per turn: it jumps at half the motor speed
    assert st.follower_jump_rad_s(dataclasses.replace(params, strokes=2)) == pytest.approx(0.5 * w)


def test_spring_force_is_displacement_driven(params: st.StructureParams) -> None:
    alpha = np.array([0.5 * math.pi, 1.5 * math.pi])
    force = st.spring_force_n(params, alpha)
    k, r_d, d0 = params.platform_spring_n_per_m, params.eccentricity_m, params.preload_m
    np.testing.assert_allclose(force, [k * (d0 + r_d), k * (d0 - r_d)])
    assert st.peak_spring_force_n(params) == pytest.approx(k * (d0 + r_d))


def test_contact_pressure_and_fatigue_by_hand(params: st.StructureParams) -> None:
    force = 100.0
    b = math.sqrt(
        4.0 * force * params.contact_radius_m / (math.pi * params.contact_width_m * params.contact_modulus_pa)
    )
    p_max = 2.0 * force / (math.pi * params.contact_width_m * b)  # eq. 21 with the Hertz half-width
    assert float(st.cam_contact_pressure_pa(params, force)) == pytest.approx(p_max, rel=1e-12)
    pe, ne = params.endurance_pa, params.endurance_cycles
    cycles = st.cycles_to_fatigue(params, np.array([0.5 * pe, pe, 2.0 * pe]))
    assert cycles[0] == math.inf and cycles[1] == math.inf
    assert cycles[2] == pytest.approx(ne * 2.0 ** (-20.0 / 3.0))


def test_shaft_load_and_bearing_life_by_hand(params: st.StructureParams) -> None:
    w_v = 800.0 * math.pi / 30.0
    load = float(st.shaft_load_peak_n(params, 0.0, w_v))
    assert load == pytest.approx(params.shaft_mass_kg * (G + params.eccentricity_m * w_v**2))
    one_rod = dataclasses.replace(params, n_rods=1)
    extra = float(st.shaft_load_peak_n(one_rod, 10.0, w_v)) - load
    assert extra == pytest.approx(params.rod_mass_kg * params.r0_m * 100.0)  # the unbalanced rod, m r0 ω_r²
    w_r = 200.0 * math.pi / 30.0
    hours = float(st.bearing_life_h(params, load, w_r))
    assert hours == pytest.approx((params.bearing_rating_n / (0.5 * load)) ** 3 * 1e6 / (200.0 * 60.0))


def test_impact_force_stores_the_impact_energy(set_a_corrected: object) -> None:
    length, r1, r2, e_star = 0.1, 0.006, 0.024, 1.1e11
    energy = np.array([1e-6, 1e-3, 2e-2])
    force = st.impact_force_n(energy, length, r1, r2, e_star)
    c = st.line_contact_compliance_m_per_n(force, length, r1, r2, e_star)
    np.testing.assert_allclose(0.5 * force**2 * c, energy, rtol=1e-9)  # E = ½ F δ, δ = c F
    assert float(st.impact_force_n(0.0, length, r1, r2, e_star)) == 0.0
    # a stiffer contact (larger E*) takes the same energy with a larger force
    assert float(st.impact_force_n(2e-2, length, r1, r2, 2 * e_star)) > float(force[2])


def test_resting_contact_energy_separates_micro_hops_from_impacts() -> None:
    weight, length, r1, r2, e_star = 0.0886 * G, 0.1, 0.006, 0.024, 1.1e11
    threshold = st.resting_contact_energy_j(weight, length, r1, r2, e_star)
    delta = float(st.line_contact_compliance_m_per_n(weight, length, r1, r2, e_star)) * weight
    assert threshold == pytest.approx(0.5 * weight * delta)
    assert 0.0 < delta < 1e-6  # an elastic approach well below a micron
    assert 3e-18 < threshold < 3e-6  # the micro-hop (3e-18 J) below it, the slipping rod's 3 µJ above
