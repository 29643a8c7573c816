"""Cam shapes: the double-acting cam is the single-acting one at twice the lift speed, everywhere."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from millctl.config import CamShape, LimitLaw, MillConfig
from millctl.errors import PhysicsInputError
from millctl.physics.cam import ellipse_for_amplitude, lift_m, strokes
from millctl.physics.detachment import find_detachment
from millctl.physics.limits import LAWS, LimitParams, omega_r_max, switch_omega_v_rad_s
from millctl.physics.model import MillModel, Scene
from millctl.physics.simulate import simulate
from millctl.physics.telemetry import revolution_summary
from millctl.units import rpm_to_rad_s


@pytest.fixture(params=["set_a_paper", "set_a_corrected"])
def pair(request: pytest.FixtureRequest) -> tuple[MillModel, MillModel]:
    single: MillModel = request.getfixturevalue(request.param)
    return single, dataclasses.replace(single, cam=CamShape.DOUBLE)


def test_lift_functions() -> None:
    assert strokes(CamShape.SINGLE) == 1 and strokes(CamShape.DOUBLE) == 2
    assert lift_m(CamShape.SINGLE, 1e-3, math.pi / 2) == pytest.approx(1e-3)
    assert lift_m(CamShape.DOUBLE, 1e-3, math.pi / 4) == pytest.approx(1e-3)  # two strokes per revolution
    assert lift_m(CamShape.DOUBLE, 1e-3, 3 * math.pi / 4) == pytest.approx(-1e-3)


def test_ellipse_semi_axes_give_the_stroke() -> None:
    e = ellipse_for_amplitude(1e-3, 20e-3)
    assert e.semi_major_m - e.semi_minor_m == pytest.approx(2e-3)
    assert e.eccentricity == pytest.approx(math.sqrt(1 - (19 / 21) ** 2))
    assert e.harmonic_error == pytest.approx(0.05)
    with pytest.raises(PhysicsInputError, match="must exceed the half stroke"):
        ellipse_for_amplitude(1e-3, 0.5e-3)


def test_every_law_sees_the_lift_speed(set_a: MillModel) -> None:
    single = LimitParams(set_a.rod_mass_kg, set_a.r0_m, set_a.eccentricity_m, set_a.spring_n_per_m)
    double = dataclasses.replace(single, cam=CamShape.DOUBLE)
    w_v = rpm_to_rad_s(np.array([0.0, 150.0, 300.0, 400.0, 600.0]))
    for law in LAWS:
        np.testing.assert_array_equal(omega_r_max(law, double, w_v), omega_r_max(law, single, 2.0 * w_v))
    assert switch_omega_v_rad_s(double) == pytest.approx(switch_omega_v_rad_s(single) / 2.0)


def test_detachment_flight_and_events_see_the_lift(pair: tuple[MillModel, MillModel]) -> None:
    single, double = pair
    w_r, w_v = rpm_to_rad_s(150.0), rpm_to_rad_s(400.0)
    for alpha0 in (0.0, 0.7, 2.0):
        d = find_detachment(Scene(double, w_r, w_v, -1.0, alpha0))
        s = find_detachment(Scene(single, w_r, 2.0 * w_v, -1.0, 2.0 * alpha0))
        assert d.detached == s.detached
        assert d.time_s == pytest.approx(s.time_s, abs=1e-12)
    sim_d = simulate(Scene(double, w_r, w_v, -1.0, 0.7), 0.5)
    sim_s = simulate(Scene(single, w_r, 2.0 * w_v, -1.0, 1.4), 0.5)
    assert sim_d.impacts.size == sim_s.impacts.size > 0
    np.testing.assert_allclose(sim_d.impacts["time_s"], sim_s.impacts["time_s"], atol=1e-9)
    np.testing.assert_allclose(sim_d.impacts["energy_j"], sim_s.impacts["energy_j"], rtol=1e-6)


def test_telemetry_samples_the_lift_evenly(pair: tuple[MillModel, MillModel]) -> None:
    single, double = pair
    w_r, w_v = rpm_to_rad_s(150.0), rpm_to_rad_s(400.0)
    assert revolution_summary(double, w_r, w_v) == revolution_summary(single, w_r, 2.0 * w_v)


def test_config_cam_shape_reaches_the_model_and_the_envelope(config: MillConfig) -> None:
    from millctl.physics.model import MillModel
    from millctl.safety import Envelope
    from millctl.studies.cams import with_cam

    double = with_cam(config, CamShape.DOUBLE)
    assert MillModel.from_config(double).cam is CamShape.DOUBLE
    single_env = Envelope.from_config(config, law=LimitLaw.CORRECTED_EVERY_PHASE)
    double_env = Envelope.from_config(double, law=LimitLaw.CORRECTED_EVERY_PHASE)
    assert float(double_env.omega_r_limit_rpm(400.0)) == pytest.approx(float(single_env.omega_r_limit_rpm(800.0)))


def test_batch_kernels_see_the_lift(pair: tuple[MillModel, MillModel]) -> None:
    from millctl.physics.batch import SceneBatch, first_impacts

    single, double = pair
    w_r, w_v = rpm_to_rad_s(150.0), rpm_to_rad_s(np.array([300.0, 400.0]))
    alpha0 = np.array([0.3, 1.1])
    d = first_impacts(SceneBatch.broadcast(double, omega_r_rad_s=w_r, omega_v_rad_s=w_v, alpha0_rad=alpha0))
    s = first_impacts(
        SceneBatch.broadcast(single, omega_r_rad_s=w_r, omega_v_rad_s=2.0 * w_v, alpha0_rad=2.0 * alpha0)
    )
    assert d["found"].all()
    np.testing.assert_allclose(d["time_s"], s["time_s"], rtol=1e-12)
    np.testing.assert_allclose(d["energy_j"], s["energy_j"], rtol=1e-9)
    row = SceneBatch.from_scenes([Scene(double, w_r, float(w_v[0]), -1.0, 0.3)])
    same = SceneBatch.from_scenes([Scene(single, w_r, 2.0 * float(w_v[0]), -1.0, 0.6)])
    np.testing.assert_array_equal(first_impacts(row)["time_s"], first_impacts(same)["time_s"])
