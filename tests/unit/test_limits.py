"""Detachment limits: closed forms, the reference point, continuity and cancellation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from millctl.config import G_M_S2, LimitLaw
from millctl.physics.limits import (
    LimitParams,
    omega_r_max,
    omega_r_max_eq8a,
    regime_flags,
    switch_omega_v_rad_s,
)
from millctl.units import rad_s_to_rpm, rpm_to_rad_s


@pytest.fixture(scope="module")
def p(config) -> LimitParams:
    return LimitParams.from_config(config)


def test_reference_point_set_a(p):
    """MODEL-NOTES: printed eq. 9 ≈ 200 rpm and the paper's every-cycle bound ≈ 98.5 rpm at 800 rpm."""
    w_v = rpm_to_rad_s(800.0)
    assert rad_s_to_rpm(omega_r_max(LimitLaw.PAPER_EQ9, p, w_v)) == pytest.approx(200.0, abs=0.5)
    assert rad_s_to_rpm(omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w_v)) == pytest.approx(98.5, abs=0.1)
    assert rad_s_to_rpm(switch_omega_v_rad_s(p)) == pytest.approx(308.0, abs=0.5)


@pytest.mark.parametrize("omega_v_rpm", [0.0, 150.0, 307.0, 500.0, 800.0, 900.0])
def test_closed_forms_at_sample_points(p, omega_v_rpm):
    m, k, r_d, r0, g = p.rod_mass_kg, p.spring_n_per_m, p.eccentricity_m, p.r0_m, G_M_S2
    w = rpm_to_rad_s(omega_v_rpm)
    printed = math.sqrt((m * g - (k - m * w * w) * r_d) / (2 * m * r0))
    assert omega_r_max(LimitLaw.PAPER_EQ9, p, w) == pytest.approx(printed, rel=1e-12)
    worst = min(m * g - (k - m * w * w) * r_d, m * g + (k - m * w * w) * r_d)
    assert omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w) == pytest.approx(
        math.sqrt(max(worst, 0) / (2 * m * r0)), rel=1e-12
    )
    gamma = r_d * w * w / g
    assert omega_r_max(LimitLaw.CORRECTED_EVERY_PHASE, p, w) == pytest.approx(
        math.sqrt(max(g * (1 - gamma), 0) / r0), rel=1e-12
    )
    assert omega_r_max(LimitLaw.CORRECTED_BEST_PHASE, p, w) == pytest.approx(math.sqrt(g * (1 + gamma) / r0), rel=1e-12)
    # eq. 9 is eq. 8a at sin α = −1
    assert omega_r_max_eq8a(p, w, -1.0) == pytest.approx(printed, rel=1e-12)


def test_every_cycle_bound_is_continuous_across_switch(p):
    w_s = switch_omega_v_rad_s(p)
    eps = w_s * 1e-9
    below = omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w_s - eps)
    above = omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w_s + eps)
    assert below == pytest.approx(above, rel=1e-7)
    # and at the switch the worst phase and printed eq. 9 agree
    assert omega_r_max(LimitLaw.PAPER_EQ9, p, w_s) == pytest.approx(
        omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w_s), rel=1e-12
    )


def test_every_cycle_bound_is_below_printed_eq9_above_switch(p):
    w = np.linspace(switch_omega_v_rad_s(p) * 1.01, rpm_to_rad_s(1200.0), 50)
    assert np.all(omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w) < omega_r_max(LimitLaw.PAPER_EQ9, p, w))


def test_regime_flags(p):
    w = rpm_to_rad_s(np.array([0.0, 800.0, 1100.0]))
    flags = regime_flags(LimitLaw.CORRECTED_EVERY_PHASE, p, w)
    assert flags.spring_below_inertia.tolist() == [False, True, True]
    assert flags.gamma_ge_1.tolist() == [False, False, True]
    assert flags.no_real_limit.tolist() == [False, False, True]


def test_numerator_near_zero_keeps_its_digits():
    """Eq. 9's numerator m(g + r_d ω_v²) − k r_d near its zero: compare with exact rationals."""
    from fractions import Fraction

    m, r_d, r0, g = 0.1, 1e-3, 0.018, G_M_S2
    w_v = 50.0
    # choose k so that the numerator is 1e-9 of its terms
    k = (m * (g + r_d * w_v * w_v) - 1e-12) / r_d
    p = LimitParams(rod_mass_kg=m, r0_m=r0, eccentricity_m=r_d, spring_n_per_m=k, g_m_s2=g)
    exact = Fraction(m) * (Fraction(g) + Fraction(r_d) * Fraction(w_v) ** 2) - Fraction(k) * Fraction(r_d)
    ours = float(omega_r_max(LimitLaw.PAPER_EQ9, p, w_v)) ** 2 * 2 * m * r0
    assert ours == pytest.approx(float(exact), rel=1e-3)


@given(st.floats(0.0, 200.0), st.floats(-1.0, 1.0))
def test_eq8a_is_monotone_in_phase_when_stiff(w_v, s):
    p = LimitParams(rod_mass_kg=0.0886, r0_m=0.018, eccentricity_m=1e-3, spring_n_per_m=92.0)
    if p.spring_n_per_m > p.rod_mass_kg * w_v * w_v:
        assert omega_r_max_eq8a(p, w_v, s) >= omega_r_max_eq8a(p, w_v, -1.0) - 1e-12
    else:
        assert omega_r_max_eq8a(p, w_v, s) >= omega_r_max_eq8a(p, w_v, 1.0) - 1e-12
