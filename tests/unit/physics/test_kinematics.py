"""Eqs 1–3 with arbitrary phases, and the normal-force function as a trig sum."""

from __future__ import annotations

import math

import pytest

from millctl.config import ModelVariant
from millctl.physics.kinematics import g_eff_m_s2, normal_force_per_mass, rod_on_wall, true_normal_force_per_mass
from millctl.physics.model import MillModel, Scene


def test_eqs_1_to_3_as_printed_with_zero_phases(set_a: MillModel) -> None:
    """θ0 = α0 = 0 reproduces the printed eqs 1a–3b."""
    w_r, w_v, t = 20.0, 80.0, 0.0123
    scene = Scene(set_a, w_r, w_v, 0.0, 0.0)
    x, y, vx, vy, ax, ay = rod_on_wall(scene, t)
    r0, r_d, l_m = set_a.r0_m, set_a.eccentricity_m, set_a.cam_to_vial_m
    assert x == pytest.approx(r0 * math.cos(w_r * t))
    assert y == pytest.approx(r0 * math.sin(w_r * t) + l_m - (r_d - r_d * math.sin(w_v * t)))
    assert vx == pytest.approx(-w_r * r0 * math.sin(w_r * t))
    assert vy == pytest.approx(w_r * r0 * math.cos(w_r * t) + w_v * r_d * math.cos(w_v * t))
    assert ax == pytest.approx(-(w_r**2) * r0 * math.cos(w_r * t))
    assert ay == pytest.approx(-(w_v**2 * r_d * math.sin(w_v * t) + w_r**2 * r0 * math.sin(w_r * t)))


def test_velocity_and_acceleration_are_derivatives_with_phases(set_a: MillModel) -> None:
    scene = Scene(set_a, 17.0, 95.0, 1.3, -0.4)
    t, h = 0.037, 1e-6
    p0, p1, p2 = rod_on_wall(scene, t - h), rod_on_wall(scene, t), rod_on_wall(scene, t + h)
    for i in (0, 1):
        assert p1[2 + i] == pytest.approx((p2[i] - p0[i]) / (2 * h), rel=1e-6)
        assert p1[4 + i] == pytest.approx((p2[2 + i] - p0[2 + i]) / (2 * h), rel=1e-6)


@pytest.mark.parametrize("variant", list(ModelVariant))
def test_normal_force_trig_sum_matches_the_direct_form(set_a: MillModel, variant: ModelVariant) -> None:
    scene = Scene(set_a, 14.0, 70.0, 0.7, 2.1)
    f = normal_force_per_mass(scene, 0.7, variant)
    m = set_a
    for t in (0.0, 0.011, 0.29):
        theta, alpha = 0.7 + 14.0 * t, 2.1 + 70.0 * t
        if variant is ModelVariant.CORRECTED:
            direct = true_normal_force_per_mass(scene, t, theta)
            assert direct == pytest.approx(m.r0_m * 14.0**2 - g_eff_m_s2(scene, t) * math.sin(theta))
        else:
            k_m = m.spring_n_per_m / m.rod_mass_kg
            direct = 2 * m.r0_m * 14.0**2 - (
                m.g_m_s2 + (k_m - 70.0**2) * m.eccentricity_m * math.sin(alpha)
            ) * math.sin(theta)
        assert f(t) == pytest.approx(direct, rel=1e-12, abs=1e-12)
        assert f(t, 1) == pytest.approx((f(t + 1e-7) - f(t - 1e-7)) / 2e-7, rel=1e-5, abs=1e-6)
