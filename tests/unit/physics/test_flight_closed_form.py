"""r_d = 0: detachment and flight time have closed forms (MODEL-NOTES; docs/model.md#eq-10)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from millctl.config import ModelVariant
from millctl.physics.detachment import find_detachment
from millctl.physics.events import WALL, earliest_contact
from millctl.physics.flight import RodState, WallState, depart
from millctl.physics.model import MillModel, Scene


@pytest.fixture(scope="module")
def still_cam(set_a_corrected: MillModel) -> MillModel:
    return dataclasses.replace(set_a_corrected, eccentricity_m=0.0, n_rods=1)


@pytest.mark.parametrize("omega_r", [5.0, 10.0, 15.0, 20.0, 22.0, 23.3])
@pytest.mark.parametrize("theta0", [-0.5 * math.pi, -2.5, -0.2])
def test_flight_time_closed_form(still_cam: MillModel, omega_r: float, theta0: float) -> None:
    """Flight time 4 r0 ω_r cos θ_d / g to 1e-12 relative; sin θ_d = r0 ω_r² / g."""
    scene = Scene(still_cam, omega_r, 50.0, theta0, 0.7)
    det = find_detachment(scene)
    assert det.detached
    r0, g = still_cam.r0_m, still_cam.g_m_s2
    assert math.sin(det.theta_rad) == pytest.approx(r0 * omega_r**2 / g, rel=1e-12)
    flight = depart(scene, WallState(0.0, theta0), det.time_s)
    states: list[RodState] = [flight]
    contact = earliest_contact(scene, states, det.time_s, det.time_s + 2.0)
    assert contact is not None and contact.partner == WALL
    t_f = contact.time_s - det.time_s
    expected = 4.0 * r0 * omega_r * math.cos(det.theta_rad) / g
    assert t_f == pytest.approx(expected, rel=1e-12)


def test_paper_variant_detaches_at_eq7(set_a_paper: MillModel) -> None:
    """Paper variant, r_d = 0: sin θ_d = 2 r0 ω_r² / g (printed eq. 7 with r_d = 0)."""
    model = dataclasses.replace(set_a_paper, eccentricity_m=0.0)
    omega_r = 12.0
    det = find_detachment(Scene(model, omega_r, 80.0))
    assert det.detached
    assert math.sin(det.theta_rad) == pytest.approx(2 * model.r0_m * omega_r**2 / model.g_m_s2, rel=1e-12)
    assert model.variant is ModelVariant.PAPER
