"""Issue 20 item 3: the slip level of detail (stick → slip → detach, with the rod's spin).

References: closed forms (the rolling rod with r_d = 0; the flight 4 r0 ω cos θ_d/g), the
certified no-slip detachment, and the sliding block's equations integrated again here with
scipy at tight tolerance.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import pytest
from scipy.integrate import solve_ivp

from millctl.errors import PhysicsInputError
from millctl.physics.detachment import find_detachment
from millctl.physics.model import MillModel, Scene
from millctl.physics.slip_ride import fly_to_wall, ride, slip_effect
from millctl.units import rpm_to_rad_s

W_R, W_V = rpm_to_rad_s(200.0), rpm_to_rad_s(800.0)

State = Sequence[float]
"""The sliding block's state for solve_ivp: (angle φ, angular rate φ')."""


@dataclasses.dataclass(frozen=True)
class FallingZero:
    """A solve_ivp event: ``f(t, y)`` crossing zero downwards ends the integration."""

    f: Callable[[float, State], float]
    terminal: bool = True
    direction: float = -1.0

    def __call__(self, t: float, y: State) -> float:
        return self.f(t, y)


@pytest.mark.parametrize("alpha0", [0.3, 2.0, 4.4])
def test_locked_spin_with_unbounded_friction_is_the_paper_carriage(set_a_corrected: MillModel, alpha0: float) -> None:
    """μ = ∞, spin locked: the ride is the carriage, and detaches where the certified N = 0 search says."""
    scene = Scene(set_a_corrected, W_R, W_V, -0.5 * math.pi, alpha0)
    r = ride(scene, "locked", friction=math.inf)
    det = find_detachment(scene)
    assert r.detached and det.detached
    assert r.time_s == pytest.approx(det.time_s, abs=1e-9)
    assert r.theta_rate_rad_s == pytest.approx(W_R, rel=1e-12) and r.spin_rad_s == pytest.approx(W_R, rel=1e-12)


@pytest.mark.parametrize("omega_r", [30.0, 35.0, 40.0])
def test_free_rod_rolls_and_detaches_where_energy_says(set_a_corrected: MillModel, omega_r: float) -> None:
    """r_d = 0, rolling (j = 2): φ̇² = ω_r² − (4/3)(g/r0)(sin φ + 1); N = 0 gives sin φ_d = (r0 ω_r² − 4g/3)/(7g/3)."""
    model = dataclasses.replace(set_a_corrected, eccentricity_m=0.0)
    r = ride(Scene(model, omega_r, 0.0, -0.5 * math.pi, 0.0), "free", friction=math.inf)
    g, r0 = model.g_m_s2, model.r0_m
    sin_d = (r0 * omega_r**2 - 4.0 * g / 3.0) / (7.0 * g / 3.0)
    assert r.detached
    assert math.sin(r.theta_rad) == pytest.approx(sin_d, abs=1e-8)
    assert r.theta_rate_rad_s**2 == pytest.approx(omega_r**2 - 4.0 * g / (3.0 * r0) * (sin_d + 1.0), rel=1e-7)
    # rolling: the contact point keeps the wall's speed, so the spin follows from φ̇
    assert r0 * r.theta_rate_rad_s + model.rod_radius_m * r.spin_rad_s == pytest.approx(
        model.vial_radius_m * omega_r, rel=1e-9
    )


def test_free_rod_at_the_operating_point_is_not_carried(set_a_corrected: MillModel) -> None:
    """200/800 rpm, μ = 0.3: the rolling rod rocks about the bottom; it stays on the wall for a revolution."""
    r = ride(Scene(set_a_corrected, W_R, W_V, -0.5 * math.pi, 1.0), "free")
    assert not r.detached and r.slip_time_s > 0.0
    assert {p.mode for p in r.phases} == {"stick", "slip"}


def test_sliding_block_against_an_independent_integration(set_a_corrected: MillModel) -> None:
    """Locked spin, μ = 0.3, a phase that detaches: carriage to the grip loss, then the block slides to N = 0."""
    model, alpha0 = set_a_corrected, 2.0 * math.pi * 9.5 / 16
    scene = Scene(model, W_R, W_V, -0.5 * math.pi, alpha0)
    r = ride(scene, "locked")
    assert r.detached and [p.mode for p in r.phases] == ["stick", "slip"]
    mu, r0, g, c = model.powder_friction, model.r0_m, model.g_m_s2, model.eccentricity_m * W_V**2

    def g_eff(t: float) -> float:
        return g - c * math.sin(alpha0 + W_V * t)

    def n(t: float, y: State) -> float:
        return r0 * y[1] ** 2 - g_eff(t) * math.sin(y[0])

    def lose_grip(t: float, y: State) -> float:  # carriage: φ = −π/2 + ω_r t; grip lost where μ n = |g_eff cos φ|
        return mu * n(t, y) - abs(g_eff(t) * math.cos(y[0]))

    def slide(t: float, y: State) -> list[float]:
        return [y[1], (mu * n(t, y) - g_eff(t) * math.cos(y[0])) / r0]

    grip, off = FallingZero(lose_grip), FallingZero(n)
    carried = solve_ivp(
        lambda t, y: [y[1], 0.0], (0, 1), [-0.5 * math.pi, W_R], events=grip, rtol=1e-12, atol=1e-14, max_step=1e-4
    )
    t1, y1 = carried.t_events[0][0], carried.y_events[0][0]
    slid = solve_ivp(slide, (t1, 1), y1, events=off, rtol=1e-12, atol=1e-14, max_step=1e-4, method="LSODA")
    assert r.phases[1].t_start_s == pytest.approx(t1, abs=1e-9)
    assert r.time_s == pytest.approx(slid.t_events[0][0], abs=1e-7)
    assert r.theta_rad == pytest.approx(slid.y_events[0][0][0], abs=1e-7)


def test_flight_from_the_carriage_is_the_closed_form(set_a_corrected: MillModel) -> None:
    """r_d = 0, departure at sin θ_d = r0 ω²/g with φ̇ = ω: flight 4 r0 ω cos θ_d / g; mirrored for φ̇ < 0."""
    model = dataclasses.replace(set_a_corrected, eccentricity_m=0.0)
    omega = 15.0
    theta_d = math.asin(model.r0_m * omega**2 / model.g_m_s2)
    scene = Scene(model, omega, 0.0)
    expected = 4 * model.r0_m * omega * math.cos(theta_d) / model.g_m_s2
    landing = fly_to_wall(scene, 0.7, theta_d, omega)
    mirrored = fly_to_wall(scene, 0.7, math.pi - theta_d, -omega)
    assert landing is not None and mirrored is not None
    assert landing.flight_time_s == pytest.approx(expected, rel=1e-12)
    assert mirrored.flight_time_s == pytest.approx(expected, rel=1e-12)
    assert math.remainder(
        mirrored.landing_theta_rad - (math.pi - landing.landing_theta_rad), 2 * math.pi
    ) == pytest.approx(0.0, abs=1e-12)


def test_slip_effect_rows_and_bad_input(set_a_corrected: MillModel) -> None:
    effect = slip_effect(set_a_corrected, W_R, W_V, phases=2)
    assert [r["model"] for r in effect["rows"]] == ["no-slip", "slip, spin locked", "slip, spin free"]
    assert effect["rows"][0]["detach_fraction"] == 1.0 and effect["rows"][2]["detach_fraction"] == 0.0
    with pytest.raises(PhysicsInputError, match="spin"):
        ride(Scene(set_a_corrected, W_R, W_V), "wobbly")  # type: ignore[arg-type]
    with pytest.raises(PhysicsInputError, match="friction"):
        ride(Scene(set_a_corrected, W_R, W_V), "free", friction=-1.0)
