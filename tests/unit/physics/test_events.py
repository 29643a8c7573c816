"""Exact collision events on the hard cases of MODEL-NOTES, against the paper's fixed-step scheme."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from millctl.physics.detachment import find_detachment
from millctl.physics.events import WALL, earliest_contact
from millctl.physics.flight import FlightState, RodState, WallState, depart
from millctl.physics.legacy import legacy_first_contact
from millctl.physics.methods import first_impact
from millctl.physics.model import MillModel, Scene
from millctl.physics.reference import closed_form_flight_time_s, reference_first_impact


@pytest.fixture(scope="module")
def one_rod(set_a_corrected: MillModel) -> MillModel:
    return dataclasses.replace(set_a_corrected, n_rods=1)


def test_near_limit_omega_r_short_flight(one_rod: MillModel) -> None:
    """ω_r within 1e-5 of √(g/r0) (r_d = 0): a ~1 ms flight, exact to 1e-10; the paper's step of 1 ms is 50 % off."""
    model = dataclasses.replace(one_rod, eccentricity_m=0.0)
    omega = math.sqrt(model.g_m_s2 / model.r0_m) * (1.0 - 1e-5)
    scene = Scene(model, omega, 0.0, -0.5 * math.pi, 0.0)
    det = find_detachment(scene)
    expected = closed_form_flight_time_s(model.r0_m, omega, det.theta_rad, model.g_m_s2)
    assert 5e-4 < expected < 2e-3
    event = first_impact(scene)
    assert event is not None and event.partner == WALL
    assert event.time_s - det.time_s == pytest.approx(expected, rel=1e-10)
    legacy = first_impact(scene, "legacy", dt=1e-3)
    assert legacy is not None
    assert abs(legacy.time_s - det.time_s - expected) > 0.2 * expected


def _grazing_pair(model: MillModel, delta_m: float) -> tuple[Scene, FlightState, WallState, float]:
    """A flight whose apex passes at 2 r_r + δ below a pinned rod at the top (ω_r = ω_v = r_d = 0)."""
    model = dataclasses.replace(model, eccentricity_m=0.0, n_rods=2)
    scene = Scene(model, 0.0, 0.0, 0.5 * math.pi, 0.0)
    partner = WallState(0.0, 0.5 * math.pi)
    t_apex, vx = 0.01, 0.2
    apex_y = model.r0_m - model.contact_distance_m - delta_m
    flight = FlightState(0.0, -vx * t_apex, apex_y - 0.5 * model.g_m_s2 * t_apex**2, vx, model.g_m_s2 * t_apex)
    return scene, flight, partner, t_apex


@pytest.mark.parametrize("rel", [1e-9, -1e-9])
def test_grazing_rod_rod_contact(set_a_corrected: MillModel, rel: float) -> None:
    """Closest approach 2 r_r (1 ± 1e-9): the engine touches only when it should; a 1.3 ms step check misses it."""
    scene, flight, partner, t_apex = _grazing_pair(set_a_corrected, rel * set_a_corrected.contact_distance_m)
    states: list[RodState] = [flight, partner]
    contact = earliest_contact(scene, states, 0.0, 2 * t_apex)
    if rel > 0:
        assert contact is None
        return
    assert contact is not None and contact.partner == 1
    assert contact.time_s == pytest.approx(t_apex, abs=1e-5)
    assert abs(contact.normal_velocity_m_s) < 1e-3  # grazing: almost no approach speed
    steps = np.arange(0.0, 2 * t_apex, 1.3e-3)
    x, y, _, _ = flight.rel_array(scene, steps)
    gap2 = (x - 0.0) ** 2 + (y - scene.model.r0_m) ** 2 - scene.model.contact_distance_m**2
    assert np.all(gap2 > 0.0)  # the paper's "distance ≤ contact" check never fires


def test_tiny_steps_fake_a_collision_at_departure(one_rod: MillModel) -> None:
    """dt = 1e-8 s in absolute coordinates: the paper's check fires right after departure; exact does not."""
    scene = Scene(one_rod, 15.0, 80.0, -0.5 * math.pi, 0.3)
    det = find_detachment(scene)
    exact = first_impact(scene)
    assert exact is not None and exact.time_s - det.time_s > 0.05
    fake = legacy_first_contact(scene, 1e-8, None, t_end_s=det.time_s + 2e-5)
    assert fake is not None and fake[0] - det.time_s < 1e-6
    ref = reference_first_impact(scene, digits=30)
    assert ref is not None and exact.time_s == pytest.approx(ref.time_s, rel=1e-12)


@pytest.mark.parametrize("tol", [1e-3, 1e-6, 0.0])
def test_huge_and_tiny_tolerances(one_rod: MillModel, tol: float) -> None:
    """The exact engine's error follows its tolerance from 1 ms down to ulps; a 30 ms legacy step is 10 ms off."""
    scene = Scene(one_rod, 15.0, 80.0, -0.5 * math.pi, 0.3)
    ref = reference_first_impact(scene, digits=30)
    event = first_impact(scene, tol=tol)
    assert ref is not None and event is not None
    assert abs(event.time_s - ref.time_s) <= max(tol, 1e-15 * ref.time_s)
    if tol == 1e-3:
        legacy = first_impact(scene, "legacy", dt=0.03)
        assert legacy is not None and abs(legacy.time_s - ref.time_s) > 5e-3


def test_gamma_above_one_hops_every_cam_cycle(set_a_corrected: MillModel) -> None:
    """Γ = 1.5: rods leave the wall in most cam cycles at any ω_r; the first impact still matches mpmath."""
    w_v = math.sqrt(1.5 * set_a_corrected.g_m_s2 / set_a_corrected.eccentricity_m)
    scene = Scene(set_a_corrected, 35.0, w_v, -0.5 * math.pi, 0.0)
    det = find_detachment(scene)
    assert det.detached
    event, ref = first_impact(scene), reference_first_impact(scene, digits=30)
    assert event is not None and ref is not None
    assert event.time_s == pytest.approx(ref.time_s, rel=1e-12)
    assert math.hypot(event.x_m - ref.x_m, event.y_m - ref.y_m) < 1e-12


@pytest.mark.parametrize("variant_fixture", ["set_a_corrected", "set_a_paper"])
def test_packing_limit(request: pytest.FixtureRequest, variant_fixture: str) -> None:
    """n at the packing limit (neighbours 1e-9 apart): first impacts are exact, no contact is faked at the start."""
    model: MillModel = request.getfixturevalue(variant_fixture)
    r_r = model.vial_radius_m / 3.0 * (1.0 - 1e-9)  # r0 sin(π/6) = r_r ⇔ r_r = r_v/3
    model = dataclasses.replace(model, rod_radius_m=r_r, n_rods=6)
    scene = Scene(model, 10.0, 60.0, -0.5 * math.pi, 0.2)
    event, ref = first_impact(scene), reference_first_impact(scene, digits=30)
    assert event is not None and ref is not None
    assert (event.rod, event.partner) == (ref.rod, ref.partner)
    # positions carry ~1e-18 m of rounding; at a ~1e-5 m/s approach that is ~1e-13 s
    assert event.time_s == pytest.approx(ref.time_s, rel=1e-10, abs=1e-13)


def test_departing_rod_keeps_its_own_state(set_a_corrected: MillModel) -> None:
    """Each rod detaches at its own time: rod 1 (60° ahead) is still pinned while rod 0 flies (eqs 11–12 corrected)."""
    scene = Scene(set_a_corrected, 12.0, 50.0, -0.5 * math.pi, 0.0)
    det0 = find_detachment(scene, scene.rod_theta0_rad(0))
    det1 = find_detachment(scene, scene.rod_theta0_rad(1))
    assert det0.detached and det1.detached and det1.time_s < det0.time_s
    flight = depart(scene, WallState(0.0, scene.rod_theta0_rad(0)), det0.time_s)
    x, y, _, _ = flight.rel(scene, det0.time_s)
    assert math.hypot(x, y) == pytest.approx(scene.model.r0_m, rel=1e-15)
    theta = math.atan2(y, x)
    assert theta == pytest.approx(
        math.remainder(scene.rod_theta0_rad(0) + scene.omega_r_rad_s * det0.time_s, 2 * math.pi)
    )
