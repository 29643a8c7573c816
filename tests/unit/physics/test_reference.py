"""Agreement with an independent high-precision evaluation (mpmath) on random scenes."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from millctl.config import ModelVariant
from millctl.physics.methods import first_impact
from millctl.physics.model import MillModel, Scene
from millctl.physics.reference import closed_form_flight_time_s, reference_first_impact
from millctl.physics.simulate import simulate


@pytest.mark.parametrize("seed", range(8))
def test_first_impact_matches_mpmath(set_a: MillModel, seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    variant = ModelVariant.CORRECTED if seed % 2 else ModelVariant.PAPER
    model = dataclasses.replace(set_a, variant=variant, restitution=float(rng.uniform(0.0, 0.8)))
    scene = Scene(
        model,
        float(rng.uniform(4.0, 15.0 if variant is ModelVariant.PAPER else 23.0)),  # below eq. 7's best phase
        float(rng.uniform(0.0, 125.0)),
        float(rng.uniform(-math.pi, math.pi)),
        float(rng.uniform(0.0, 2 * math.pi)),
    )
    event = first_impact(scene)
    ref = reference_first_impact(scene, digits=30)
    assert event is not None and ref is not None
    assert event.time_s == pytest.approx(ref.time_s, rel=1e-11, abs=1e-13)
    assert math.hypot(event.x_m - ref.x_m, event.y_m - ref.y_m) < 1e-11
    assert event.normal_velocity_m_s == pytest.approx(ref.normal_velocity_m_s, rel=1e-8, abs=1e-12)
    assert event.energy_j == pytest.approx(ref.energy_j, rel=1e-8, abs=1e-15)
    assert event.tangential_velocity_m_s == pytest.approx(ref.tangential_velocity_m_s, rel=1e-8, abs=1e-12)


def test_ivp_converges_to_the_reference(set_a_corrected: MillModel) -> None:
    """One rod leaving with N = 0 (solve_ivp cannot tell the departure root from a contact when a rod starts
    unsupported, a spurious event at t = 0 the benchmark counts)."""
    scene = Scene(dataclasses.replace(set_a_corrected, n_rods=1), 12.0, 70.0, -0.5 * math.pi, 1.1)
    ref = reference_first_impact(scene, digits=30)
    coarse, fine = first_impact(scene, "ivp", tol=1e-5), first_impact(scene, "ivp", tol=1e-11)
    assert ref is not None and coarse is not None and fine is not None
    assert abs(fine.time_s - ref.time_s) < abs(coarse.time_s - ref.time_s) + 1e-15
    assert fine.time_s == pytest.approx(ref.time_s, rel=1e-8)


def test_closed_form_against_a_departure_with_negative_normal_force(set_a_paper: MillModel) -> None:
    """Paper variant, r_d = 0: the rod leaves where the true N < 0; flight 2(a + √(a² − n_d))/g, a = r0 ω cos θ_d."""
    model = dataclasses.replace(set_a_paper, eccentricity_m=0.0, n_rods=1)
    omega = 12.0
    scene = Scene(model, omega, 0.0, -0.5 * math.pi, 0.0)
    run = simulate(scene, 2.0, stop_after_first=True)
    theta_d, t_d = float(run.detachments[0]["theta_rad"]), float(run.detachments[0]["time_s"])
    n_d = model.r0_m * (model.r0_m * omega**2 - model.g_m_s2 * math.sin(theta_d))
    assert n_d < 0.0  # the printed eq. 7 lets go late (its factor 2)
    expected = closed_form_flight_time_s(model.r0_m, omega, theta_d, model.g_m_s2, n_d)
    assert float(run.impacts[0]["time_s"]) - t_d == pytest.approx(expected, rel=1e-12)
