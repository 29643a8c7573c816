"""Impact and shear, eqs 18–27: each erratum of docs/model.md with its Set A number."""

from __future__ import annotations

import dataclasses
import math

import pytest

from millctl.config import ModelVariant
from millctl.physics import impact
from millctl.physics.model import MillModel
from millctl.physics.telemetry import revolution_summary
from millctl.units import rpm_to_rad_s

W_R = rpm_to_rad_s(200.0)


@pytest.fixture(scope="module")
def n_c(set_a: MillModel) -> float:
    """N_c = m ω_r² r0 at 200 rpm (the paper's centrifugal load), ≈ 0.699 N."""
    return set_a.rod_mass_kg * W_R**2 * set_a.r0_m


def test_eq18_rate_counts_every_rod(set_a_paper: MillModel, set_a_corrected: MillModel) -> None:
    assert impact.impact_rate_hz(set_a_paper, 1.0, W_R) == pytest.approx(W_R / (2 * math.pi))
    assert impact.impact_rate_hz(set_a_corrected, 1.0, W_R) == pytest.approx(6 * W_R / (2 * math.pi))


def test_eq19_energy_uses_relative_normal_velocity(set_a_paper: MillModel, set_a_corrected: MillModel) -> None:
    m = set_a_corrected.rod_mass_kg
    assert impact.impact_energy_j(set_a_paper, 0.02, 0.2, True) == pytest.approx(0.5 * m * 0.04)
    assert impact.impact_energy_j(set_a_corrected, 0.02, 0.2, True) == pytest.approx(0.5 * m * 0.02**2)
    assert impact.impact_energy_j(set_a_corrected, 0.02, 0.2, False) == pytest.approx(0.25 * m * 0.02**2)
    bouncy = dataclasses.replace(set_a_corrected, restitution=0.5)
    assert impact.impact_energy_j(bouncy, 0.02, 0.2, True) == pytest.approx(0.5 * m * 0.75 * 0.02**2)


def test_eq23_hertz_line_contact(set_a_paper: MillModel, set_a_corrected: MillModel, n_c: float) -> None:
    """b: corrected √(4 N R'/(π L E*)) = 0.808 µm; printed (π/4, convex R) 0.491 µm."""
    assert impact.hertz_half_width_m(set_a_corrected, n_c) == pytest.approx(0.8078e-6, rel=1e-3)
    assert impact.hertz_half_width_m(set_a_paper, n_c) == pytest.approx(0.4914e-6, rel=1e-3)
    e_star = impact.effective_modulus_pa(set_a_corrected)
    r = impact.contact_radius_m(set_a_corrected)
    b = math.sqrt(4 * n_c * r / (math.pi * set_a_corrected.rod_length_m * e_star))
    assert impact.hertz_half_width_m(set_a_corrected, n_c) == pytest.approx(b, rel=1e-15)


def test_eq23_uses_both_moduli(set_a_corrected: MillModel, set_a_paper: MillModel) -> None:
    """A tungsten-carbide rod in a steel bore: the printed E₂-twice form ignores the rod's modulus."""
    wc = dataclasses.replace(set_a_corrected, rod_youngs_pa=620e9, rod_poisson=0.22)
    wc_paper = dataclasses.replace(set_a_paper, rod_youngs_pa=620e9, rod_poisson=0.22)
    expected = 1 / ((1 - 0.22**2) / 620e9 + (1 - 0.29**2) / 200e9)
    assert impact.effective_modulus_pa(wc) == pytest.approx(expected)
    assert impact.effective_modulus_pa(wc_paper) == pytest.approx(1 / ((1 - 0.22**2 + 1 - 0.29**2) / 200e9))


def test_eq24_concave_contact_radius(set_a_paper: MillModel, set_a_corrected: MillModel) -> None:
    assert impact.contact_radius_m(set_a_corrected) == pytest.approx(8.0e-3)
    assert impact.contact_radius_m(set_a_paper) == pytest.approx(4.8e-3)


def test_eq21_22_25_pressures_and_shear(set_a_corrected: MillModel, set_a_paper: MillModel, n_c: float) -> None:
    b = impact.hertz_half_width_m(set_a_corrected, n_c)
    L = set_a_corrected.rod_length_m
    assert impact.peak_pressure_pa(set_a_corrected, n_c) == pytest.approx(2 * n_c / (math.pi * L * b))
    assert impact.mean_pressure_pa(set_a_corrected, n_c) == pytest.approx(n_c / (2 * L * b))
    assert impact.wall_shear_pa(set_a_corrected, n_c) == pytest.approx(1.2987e6, rel=1e-3)
    assert impact.wall_shear_pa(set_a_paper, n_c) == pytest.approx(2.1348e6, rel=1e-3)
    assert impact.wall_shear_pa(set_a_corrected, 0.0) == 0.0


def test_eq27_spin_shear_sign_follows_the_cam(set_a_corrected: MillModel, n_c: float) -> None:
    up = impact.spin_shear_pa(set_a_corrected, n_c, 1.0, 0.0)
    assert up > 0.0 and impact.spin_shear_pa(set_a_corrected, n_c, -1.0, 0.0) == pytest.approx(-up)
    assert impact.spin_shear_pa(set_a_corrected, n_c, 1.0, 0.5 * math.pi) == pytest.approx(0.0, abs=1e-9 * up)


def test_eq20_rod_rod_shear(set_a_corrected: MillModel) -> None:
    assert impact.rod_rod_shear_pa(set_a_corrected, 0.5, 1e-6) == pytest.approx(0.3 * 0.5 / 1e-6)
    assert impact.rod_rod_shear_pa(set_a_corrected, 0.5, 0.0) == 0.0


def test_eqs21_27_normal_force_varies(set_a_corrected: MillModel, n_c: float) -> None:
    """N = m(r0 ω_r² − g sin θ) along the pinned arc: mean shear 1.10 MPa, not 1.30 MPa at constant N_c."""
    s = revolution_summary(set_a_corrected, W_R, rpm_to_rad_s(800.0))
    assert s.mean_shear_pa == pytest.approx(1.097e6, rel=1e-3)
    assert s.mean_shear_pa < impact.wall_shear_pa(set_a_corrected, n_c)
    assert set_a_corrected.variant is ModelVariant.CORRECTED
