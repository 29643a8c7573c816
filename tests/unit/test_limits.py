"""Detachment limits: closed forms, the reference point, continuity and cancellation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from millctl.config import G_M_S2, LimitLaw, MillConfig
from millctl.physics.limits import (
    LimitParams,
    omega_r_max,
    omega_r_max_eq8a,
    regime_flags,
    switch_omega_v_rad_s,
)
from millctl.safety import Envelope
from millctl.units import rad_s_to_rpm, rpm_to_rad_s


@pytest.fixture(scope="module")
def p(config: MillConfig) -> LimitParams:
    return LimitParams.from_config(config)


def test_reference_point_set_a(p: LimitParams) -> None:
    """MODEL-NOTES: printed eq. 9 ≈ 200 rpm and the paper's every-cycle bound ≈ 98.5 rpm at 800 rpm."""
    w_v = rpm_to_rad_s(800.0)
    assert rad_s_to_rpm(omega_r_max(LimitLaw.PAPER_EQ9, p, w_v)) == pytest.approx(200.0, abs=0.5)
    assert rad_s_to_rpm(omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w_v)) == pytest.approx(98.5, abs=0.1)
    assert rad_s_to_rpm(switch_omega_v_rad_s(p)) == pytest.approx(308.0, abs=0.5)


# Independent oracle: ω_r,max in rad/s for Set A, computed once with mpmath at 40 digits from the raw
# parameters (m = ρ·π·r_r²·L = 7832·π·0.006²·0.1 kg, g = 9.80665, k = 92 N/m, r_d = 1 mm, r0 = 18 mm),
# never from millctl: printed eq. 9 √((mg + r_d(mω_v² − k))/(2 m r0)); the paper's every-cycle bound (the
# smaller numerator of sin α = ±1 in eq. 8a, clipped at 0); the corrected every-phase √(g(1 − Γ)/r0) and
# best-phase √(g(1 + Γ)/r0) with Γ = r_d ω_v²/g (docs/model.md).
SET_A_LIMITS_RAD_S = {
    # ω_v rpm: (printed eq. 9, paper every-cycle, corrected every-phase, corrected best-phase)
    0.0: (15.606280276456491, 15.606280276456491, 23.341248657449517, 23.341248657449517),
    150.0: (15.824344410196457, 15.824344410196457, 23.045739410973279, 23.633063127307276),
    307.0: (16.500480940408749, 16.500480940408749, 22.077004201067089, 24.540449533043275),
    500.0: (17.880445716312333, 15.003451265455453, 19.811743461783836, 26.403079342800968),
    800.0: (20.94065740923165, 10.310322796017615, 12.446027139690074, 30.573259332558508),
    900.0: (22.142630694986286, 7.3836166473036789, 7.1647518334148153, 32.222571420408968),
}


@pytest.mark.parametrize("omega_v_rpm", sorted(SET_A_LIMITS_RAD_S))
def test_laws_match_independent_high_precision_values(p: LimitParams, omega_v_rpm: float) -> None:
    w = rpm_to_rad_s(omega_v_rpm)
    printed, every_cycle, every_phase, best_phase = SET_A_LIMITS_RAD_S[omega_v_rpm]
    assert omega_r_max(LimitLaw.PAPER_EQ9, p, w) == pytest.approx(printed, rel=1e-12)
    assert omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w) == pytest.approx(every_cycle, rel=1e-12)
    assert omega_r_max(LimitLaw.CORRECTED_EVERY_PHASE, p, w) == pytest.approx(every_phase, rel=1e-12)
    assert omega_r_max(LimitLaw.CORRECTED_BEST_PHASE, p, w) == pytest.approx(best_phase, rel=1e-12)
    # eq. 9 is eq. 8a at sin α = −1
    assert omega_r_max_eq8a(p, w, -1.0) == pytest.approx(printed, rel=1e-12)


def test_every_cycle_bound_is_continuous_across_switch(p: LimitParams) -> None:
    w_s = switch_omega_v_rad_s(p)
    eps = w_s * 1e-9
    below = omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w_s - eps)
    above = omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w_s + eps)
    assert below == pytest.approx(above, rel=1e-7)
    # and at the switch the worst phase and printed eq. 9 agree
    assert omega_r_max(LimitLaw.PAPER_EQ9, p, w_s) == pytest.approx(
        omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w_s), rel=1e-12
    )


def test_every_cycle_bound_is_below_printed_eq9_above_switch(p: LimitParams) -> None:
    w = np.linspace(switch_omega_v_rad_s(p) * 1.01, rpm_to_rad_s(1200.0), 50)
    assert np.all(omega_r_max(LimitLaw.PAPER_EVERY_CYCLE, p, w) < omega_r_max(LimitLaw.PAPER_EQ9, p, w))


def test_regime_flags(p: LimitParams) -> None:
    w = rpm_to_rad_s(np.array([0.0, 800.0, 1100.0]))
    flags = regime_flags(LimitLaw.CORRECTED_EVERY_PHASE, p, w)
    assert flags.spring_below_inertia.tolist() == [False, True, True]
    assert flags.gamma_ge_1.tolist() == [False, False, True]
    assert flags.no_real_limit.tolist() == [False, False, True]


def test_numerator_near_zero_keeps_its_digits() -> None:
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
@example(0.0, -1.0)  # at rest, the phase's lower end
@example((92.0 / 0.0886) ** 0.5, 1.0)  # the spring exactly balances m·ω_v²
def test_eq8a_is_monotone_in_phase_when_stiff(w_v: float, s: float) -> None:
    p = LimitParams(rod_mass_kg=0.0886, r0_m=0.018, eccentricity_m=1e-3, spring_n_per_m=92.0)
    if p.spring_n_per_m > p.rod_mass_kg * w_v * w_v:
        assert omega_r_max_eq8a(p, w_v, s) >= omega_r_max_eq8a(p, w_v, -1.0) - 1e-12
    else:
        assert omega_r_max_eq8a(p, w_v, s) >= omega_r_max_eq8a(p, w_v, 1.0) - 1e-12


def _agreement_points(envelope: Envelope, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random speed pairs plus the edges: the limit itself and its neighbouring floats, the drive limits,
    zero, −0, negatives, nan and inf."""
    rng = np.random.default_rng(seed)
    w_v = rng.uniform(-10.0, 1.2 * envelope.vibration_max_rpm, count)
    w_r = rng.uniform(-10.0, 1.2 * envelope.rotary_max_rpm, count)
    edge_v = rng.uniform(0.0, envelope.vibration_max_rpm, count // 10)
    limit = envelope.omega_r_limit_rpm(edge_v)
    edges_r = [limit, np.nextafter(limit, np.inf), np.nextafter(limit, -np.inf), limit + 1e-9]
    w_r = np.concatenate([w_r, *edges_r])
    w_v = np.concatenate([w_v, *([edge_v] * len(edges_r))])
    v_max = envelope.vibration_max_rpm
    special_v = [0.0, -0.0, v_max, np.nextafter(v_max, np.inf), np.nextafter(v_max, -np.inf), np.nan, np.inf, -1.0]
    special_r = [0.0, -0.0, envelope.rotary_max_rpm, np.nan, np.inf, -np.inf, -1e-300, 1e-300]
    grid_r, grid_v = np.meshgrid(special_r, special_v)
    return np.concatenate([w_r, grid_r.ravel()]), np.concatenate([w_v, grid_v.ravel()])


@pytest.mark.parametrize("cam", ["single", "double"])
@pytest.mark.parametrize("law", list(LimitLaw))
def test_scalar_interlock_agrees_with_vectorised_on_1e5_points(config: MillConfig, law: LimitLaw, cam: str) -> None:
    """The interlock's plain-math scalar path gives bitwise the vectorised verdicts (issue 17, item 3);
    its speed (≤ 1 µs a check) is measured by ``python -m bench``, not asserted here."""
    import dataclasses

    from millctl.config.models import CamShape
    from millctl.physics.limits import scalar_limit

    base = Envelope.from_config(config, law=law)
    envelope = dataclasses.replace(base, params=dataclasses.replace(base.params, cam=CamShape(cam)))
    w_r, w_v = _agreement_points(envelope, 72_000, seed=list(LimitLaw).index(law))
    assert w_r.size >= 100_000
    vector = envelope.contains(w_r, w_v)
    for tolerance in (0.0, envelope.measurement_tolerance_rpm):
        vector_tol = envelope.contains(w_r, w_v, tolerance)
        scalar = [envelope.allows(a, b, tolerance) for a, b in zip(w_r.tolist(), w_v.tolist(), strict=True)]
        assert np.array_equal(vector_tol, scalar)
    sample = slice(0, None, 50)
    checked = [envelope.check(a, b).ok for a, b in zip(w_r[sample].tolist(), w_v[sample].tolist(), strict=True)]
    assert np.array_equal(vector[sample], checked)
    finite_v = w_v[np.isfinite(w_v)]
    law_rad_s = scalar_limit(law, envelope.params)
    limits = [law_rad_s(x) for x in rpm_to_rad_s(finite_v).tolist()]
    assert np.array_equal(omega_r_max(law, envelope.params, rpm_to_rad_s(finite_v)), limits)
