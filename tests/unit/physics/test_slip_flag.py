"""Issue 20 item 3: the flag where the paper's no-slip carriage needs |F_t|/N > μ.

References are written out here, independently of millctl.physics: the carried
rod's N/m = r0 ω_r² − g_eff sin θ and F_t/m = g_eff cos θ (g_eff = g − r_d ω_v² sin α)
sampled densely, the first crossing of μN = |F_t| refined with scipy's brentq.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest
from scipy.optimize import brentq

from millctl.physics.model import MillModel, Scene
from millctl.physics.slip import no_slip_check, traction_ratio
from millctl.physics.telemetry import revolution_summary
from millctl.units import rpm_to_rad_s

W_R, W_V = rpm_to_rad_s(200.0), rpm_to_rad_s(800.0)


def _margin(model: MillModel, w_r: float, w_v: float, theta0: float, alpha0: float) -> Callable[[float], float]:
    """μ N/m − |F_t|/m of the carried rod, as a function of time (independent of the package)."""

    def f(t: float) -> float:
        theta, alpha = theta0 + w_r * t, alpha0 + w_v * t
        g_eff = model.g_m_s2 - model.eccentricity_m * w_v * w_v * math.sin(alpha)
        normal = model.r0_m * w_r * w_r - g_eff * math.sin(theta)
        return model.powder_friction * normal - abs(g_eff * math.cos(theta))

    return f


def _first_violation(f: Callable[[float], float], t_end: float, samples: int = 20_001) -> float | None:
    ts = np.linspace(0.0, t_end, samples)
    values = np.array([f(t) for t in ts])
    bad = np.flatnonzero(values <= 0.0)
    if bad.size == 0:
        return None
    k = int(bad[0])
    return 0.0 if k == 0 else brentq(f, ts[k - 1], ts[k], xtol=1e-16, rtol=8.9e-16)


def test_ratio_at_the_top_of_the_rise_is_g_over_r0_omega_squared(set_a_corrected: MillModel) -> None:
    """θ = 0, sin α = 0: |F_t|/N = g/(r0 ω_r²) = 1.24 at 200 rpm, four times μ = 0.3."""
    ratio = float(traction_ratio(set_a_corrected, W_R, W_V, 0.0, 0.0))
    assert ratio == pytest.approx(set_a_corrected.g_m_s2 / (set_a_corrected.r0_m * W_R**2), rel=1e-14)
    assert round(ratio, 2) == 1.24
    assert float(traction_ratio(set_a_corrected, W_R, W_V, 0.5 * math.pi, -0.5 * math.pi)) == math.inf


@pytest.mark.parametrize("alpha0", [0.0, 1.0, 2.5, 4.0, 5.5])
def test_onset_agrees_with_an_independent_scan(set_a_corrected: MillModel, alpha0: float) -> None:
    scene = Scene(set_a_corrected, W_R, W_V, -0.5 * math.pi, alpha0)
    check = no_slip_check(scene)
    assert check.violated and check.detached
    expected = _first_violation(_margin(set_a_corrected, W_R, W_V, -0.5 * math.pi, alpha0), check.arc_end_s)
    assert expected is not None
    assert check.onset_time_s == pytest.approx(expected, abs=1e-12)
    assert math.sin(check.onset_theta_rad) < 0.0  # the carriage breaks below the horizontal at 200/800
    assert check.onset_time_s < check.arc_end_s


def test_carriage_holds_with_enough_friction(set_a_corrected: MillModel) -> None:
    """μ = 10 holds the rod on the bottom arc; the check then ends where the independent scan does."""
    model = dataclasses.replace(set_a_corrected, powder_friction=10.0)
    scene = Scene(model, W_R, W_V, -0.5 * math.pi, 0.0)
    check = no_slip_check(scene, horizon_s=0.03)  # the first 0.03 s: the bottom arc only
    expected = _first_violation(_margin(model, W_R, W_V, -0.5 * math.pi, 0.0), check.arc_end_s)
    assert expected is None and not check.violated and math.isnan(check.onset_theta_rad)


def test_rod_starting_unsupported_violates_at_once(set_a_corrected: MillModel) -> None:
    check = no_slip_check(Scene(set_a_corrected, W_R, W_V, 0.5 * math.pi, -0.5 * math.pi))
    assert check.violated and check.onset_time_s == 0.0


@pytest.mark.parametrize("rpm", [100.0, 200.0, 400.0])
def test_telemetry_carries_the_flag(set_a_corrected: MillModel, rpm: float) -> None:
    """Detaching (100, 200 rpm) or pinned (400 rpm, above the best-phase limit): the carriage slips somewhere."""
    s = revolution_summary(set_a_corrected, rpm_to_rad_s(rpm), W_V)
    assert s.no_slip_violated and -math.pi < s.slip_onset_theta_rad < math.pi
    assert s.detached is (rpm < 300.0)


def test_telemetry_standstill_has_no_flag(set_a_corrected: MillModel) -> None:
    s = revolution_summary(set_a_corrected, 0.0, W_V)
    assert not s.no_slip_violated and math.isnan(s.slip_onset_theta_rad)
