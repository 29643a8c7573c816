"""Issue 20 items 1–2: the corrected and new errata rows, each against an independent computation."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mpmath
import numpy as np
import pytest
from scipy.optimize import brentq

from millctl.cli import main
from millctl.physics import impact
from millctl.physics.errata import theta_d_over_cam_phase
from millctl.physics.legacy import arc_wall_sink_leading_m, arc_wall_sink_m
from millctl.physics.limits import LimitParams, eq9_vacuous_below_rad_s
from millctl.physics.model import MillModel
from millctl.units import rpm_to_rad_s
from tests.conftest import CONFIG_FILE

W_R, W_V = rpm_to_rad_s(200.0), rpm_to_rad_s(800.0)


def test_eq7_cam_phase_mean_against_an_independent_scan(set_a_corrected: MillModel) -> None:
    """θ_d over a uniform cam phase at the bottom: N(t) sampled densely, first fall refined by brentq."""
    m, phases = set_a_corrected, 90
    spread = theta_d_over_cam_phase(m, W_R, W_V, phases=phases)
    ts = np.linspace(0.0, 2 * math.pi / W_R, 60_001)
    thetas = []
    for k in range(phases):
        a0 = 2 * math.pi * (k + 0.5) / phases

        def n(t: np.ndarray, a0: float = a0) -> np.ndarray:
            g_eff = m.g_m_s2 - m.eccentricity_m * W_V**2 * np.sin(a0 + W_V * t)
            return m.r0_m * W_R**2 - g_eff * np.sin(-0.5 * math.pi + W_R * t)

        values = n(ts)
        i = int(np.flatnonzero(values <= 0.0)[0])
        t_d = brentq(n, ts[i - 1], ts[i], xtol=1e-15)
        thetas.append(math.degrees(-0.5 * math.pi + W_R * t_d))
    assert spread.detached_fraction == 1.0
    assert spread.mean_deg == pytest.approx(np.mean(thetas), abs=1e-8)
    assert spread.min_deg == pytest.approx(min(thetas), abs=1e-8)
    assert spread.max_deg == pytest.approx(max(thetas), abs=1e-8)


@pytest.mark.parametrize("q", [36, 360, 3600])
def test_arc_wall_sink_against_the_geometry(set_a: MillModel, q: int) -> None:
    """The rod centre midway between two of q points on the bore, solved in mpmath: |c − p| = r_r."""
    m = set_a
    with mpmath.workdps(40):
        phi, r_v, r_r = mpmath.pi / q, mpmath.mpf(m.vial_radius_m), mpmath.mpf(m.rod_radius_m)
        dist = lambda rho: (r_v * mpmath.cos(phi) - rho) ** 2 + (r_v * mpmath.sin(phi)) ** 2 - r_r**2  # noqa: E731
        rho = mpmath.findroot(dist, mpmath.mpf(m.r0_m))
        sink = float(rho - (r_v - r_r))
    assert arc_wall_sink_m(m, q) == pytest.approx(sink, rel=1e-12)
    # next order: relative (π r_v/(q r_r))² (3.7e-4 of it at q = 360)
    assert arc_wall_sink_leading_m(m, q) == pytest.approx(
        sink, rel=(math.pi * m.vial_radius_m / (q * m.rod_radius_m)) ** 2
    )
    old = (math.pi * m.vial_radius_m / q) ** 2 / (2 * m.rod_radius_m)
    assert old / arc_wall_sink_leading_m(m, q) == pytest.approx(m.vial_radius_m / m.r0_m, rel=1e-12)


def test_arc_wall_sink_set_a_number(set_a: MillModel) -> None:
    assert round(arc_wall_sink_m(set_a, 360) * 1e6, 2) == 2.74


def _hertz_b_from_peak(load: float, length: float, e_star: float, r_eff: float) -> float:
    """Half-width from the peak pressure route: p0 = √(W E*/(π L R')), b = 2W/(π L p0)."""
    p0 = math.sqrt(load * e_star / (math.pi * length * r_eff))
    return 2 * load / (math.pi * length * p0)


def test_eq20_area_is_the_hertz_strip_of_two_rods(set_a: MillModel) -> None:
    m = set_a
    weight = m.rod_mass_kg * m.g_m_s2
    e_star = m.rod_youngs_pa / (2 * (1 - m.rod_poisson**2))
    b = _hertz_b_from_peak(weight, m.rod_length_m, e_star, 0.5 * m.rod_radius_m)
    assert impact.rod_rod_contact_area_m2(m, weight) == pytest.approx(2 * b * m.rod_length_m, rel=1e-12)
    tau = m.powder_friction * weight / (2 * b * m.rod_length_m)
    assert impact.rod_rod_weight_shear_pa(m, weight) == pytest.approx(tau, rel=1e-12)
    assert round(tau / 1e6, 2) == 2.36


def test_eq26_27_carriage_traction_at_the_top(set_a_corrected: MillModel, set_a_paper: MillModel) -> None:
    """θ = 0, sin α = 0, 200 rpm: |F_t| = m g over the strip (5.38 MPa), capped at μN (1.30 MPa); printed 0.94."""
    m = set_a_corrected
    n = m.rod_mass_kg * m.r0_m * W_R**2
    e_star = m.rod_youngs_pa / (2 * (1 - m.rod_poisson**2))
    r_eff = 1 / (1 / m.rod_radius_m - 1 / m.vial_radius_m)
    strip = 2 * m.rod_length_m * _hertz_b_from_peak(n, m.rod_length_m, e_star, r_eff)
    uncapped, capped = impact.carriage_shear_pa(m, W_R, W_V, 0.0, 0.0)
    assert uncapped == pytest.approx(m.rod_mass_kg * m.g_m_s2 / strip, rel=1e-12)
    assert capped == pytest.approx(m.powder_friction * n / strip, rel=1e-12)
    assert (round(uncapped / 1e6, 2), round(capped / 1e6, 2)) == (5.38, 1.30)
    assert round(impact.spin_shear_pa(set_a_paper, n, 1.0, 0.0) / 1e6, 2) == 0.94
    assert impact.carriage_shear_pa(m, W_R, W_V, 0.5 * math.pi, -0.5 * math.pi) == (0.0, 0.0)  # off the wall


def test_k_makes_eq9_vacuous_below(set_a: MillModel) -> None:
    """Numerator m g − (k − m ω_v²) r_d = 0 solved in mpmath; Set A's k never makes it vacuous."""
    p = LimitParams(set_a.rod_mass_kg, set_a.r0_m, set_a.eccentricity_m, 1e5, set_a.g_m_s2)
    with mpmath.workdps(30):
        m, k, r_d, g = (mpmath.mpf(x) for x in (p.rod_mass_kg, 1e5, p.eccentricity_m, p.g_m_s2))
        root = mpmath.findroot(lambda w: m * g - (k - m * w * w) * r_d, mpmath.mpf(1000))
    assert eq9_vacuous_below_rad_s(p) == pytest.approx(float(root), rel=1e-13)
    assert eq9_vacuous_below_rad_s(dataclasses.replace(p, spring_n_per_m=set_a.spring_n_per_m)) == 0.0


def test_config_check_warns_about_a_platform_spring_rate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = CONFIG_FILE.read_text()
    assert "stiffness_n_per_m = 92.0" in text
    bad = tmp_path / "k.toml"
    bad.write_text(text.replace("stiffness_n_per_m = 92.0", "stiffness_n_per_m = 1e5"))
    assert main(["config", "check", str(bad)]) == 0
    out = capsys.readouterr().out
    assert "warning" in out and "10102.2 rpm" in out and "per-rod effective stiffness" in out
    assert main(["config", "check", str(CONFIG_FILE)]) == 0
    assert "warning" not in capsys.readouterr().out
