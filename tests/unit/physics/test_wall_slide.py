"""The slip ride inside level (c) (physics.wall_slide, kernels.slide): both engines, and against slip_ride.ride."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import millctl.physics.simulate as simulate_module
from millctl.config import ModelVariant
from millctl.errors import PhysicsInputError
from millctl.physics.events import scan_step_s
from millctl.physics.kernels import scene_row
from millctl.physics.kernels.many_event import many_events
from millctl.physics.kernels.slide import _slide_step
from millctl.physics.kinematics import g_eff_m_s2
from millctl.physics.many_agreement import first_difference, many_event_agreement
from millctl.physics.model import MillModel, Scene
from millctl.physics.simulate import MIN_HOP_RTOL, SimulationResult, simulate, simulate_compiled
from millctl.physics.slip_ride import fly_to_wall, ride
from millctl.physics.wall_slide import (
    DETACH,
    REGRIP,
    SLIDE_STEP,
    slide_direction,
    slide_step,
    slide_step_s,
    stick_slip_onset,
)

RPM = 2.0 * math.pi / 60.0
MU = 0.3


def _paper_point(model: MillModel, alpha0: float, rods: int = 1) -> Scene:
    one = dataclasses.replace(model, variant=ModelVariant.CORRECTED, n_rods=rods)
    return Scene(one, 200.0 * RPM, 800.0 * RPM, -0.5 * math.pi, alpha0)


def test_random_scenes_agree_event_for_event_with_slip(set_a: MillModel) -> None:
    agreement = many_event_agreement(set_a, 16, seed=23, revolutions=1.0, friction=MU)
    assert agreement.events > 300
    assert agreement.fraction == 1.0, agreement.differences


# (ω_r rpm, ω_v rpm, θ0, α0, r_d), corrected: a rod that lands where N is about to dip again hops on, each hop
# ~20× shorter, down to flights of 2e-13 s whose last hop only rounding decided (issue 40)
ZENO_SCENE = (177.70978716400575, 484.53561821061567, -2.0946428814881797, 2.7228462844645334, 0.0018871063886110732)


def _corrected_scene(model: MillModel, scene: tuple[float, ...]) -> Scene:
    w_r, w_v, theta0, alpha0, r_d = scene
    return Scene(dataclasses.replace(model, variant=ModelVariant.CORRECTED, eccentricity_m=r_d), w_r * RPM, w_v * RPM,
                 theta0, alpha0)  # fmt: skip


@pytest.mark.parametrize("friction", [math.inf, MU])
def test_a_zeno_chain_of_wall_hops_ends_at_the_minimum_hop(
    set_a: MillModel, friction: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    run = _corrected_scene(set_a, ZENO_SCENE)
    t_end = 2.0 * math.pi / run.omega_r_rad_s

    def wall_flights(result: SimulationResult) -> np.ndarray:
        return np.asarray(result.impacts["flight_time_s"][result.impacts["partner"] == -1])

    with monkeypatch.context() as patch:
        patch.setattr(simulate_module, "MIN_HOP_RTOL", 0.0)
        unended = wall_flights(simulate(run, t_end, friction=friction))
    assert unended.min() < 1e-12  # the chain runs down to rounding without the rule
    reference = simulate(run, t_end, friction=friction)
    compiled, _ = simulate_compiled(run, t_end, friction=friction)
    assert first_difference(reference, compiled) is None
    hop = MIN_HOP_RTOL * scan_step_s(run)
    for result in (reference, compiled):  # one hop below the minimum ends each chain: none ~20× shorter still
        assert np.count_nonzero(wall_flights(result) < hop / 10.0) == 0


def test_a_slide_that_begins_at_n_zero_to_rounding_is_a_slide_in_both_engines(set_a: MillModel) -> None:
    # a rod carried through a dip starts where N has just risen through 0: n is ±rounding there, and the sign
    # alone decided between a slide and an unsupported departure (engines parted at 50.2/1046.5 rpm)
    scene = _paper_point(set_a, 1.0)
    w_r, r0, w_lift = scene.omega_r_rad_s, scene.model.r0_m, scene.lift_omega_rad_s
    t = ((1.5 * math.pi - scene.lift_alpha0_rad) % (2.0 * math.pi)) / w_lift  # the cam's largest g_eff
    g_eff = g_eff_m_s2(scene, t)
    assert g_eff > r0 * w_r * w_r
    theta = math.asin(r0 * w_r * w_r / g_eff)  # n = r0 ω_r² − g_eff sin θ = 0
    while r0 * w_r * w_r - g_eff * math.sin(theta) >= 0.0:
        theta = math.nextafter(theta, math.pi / 2)
    scale = r0 * w_r * w_r + scene.model.g_m_s2 + scene.model.eccentricity_m * scene.lift_omega_rad_s**2
    assert -1e-15 * scale < r0 * w_r * w_r - g_eff * math.sin(theta) < 0.0
    h, row = slide_step_s(scene), scene_row(scene)
    for phi, slides in ((theta, True), (theta + 1e-3, False)):  # zero to rounding; clearly below zero
        step = slide_step(scene, t, phi, w_r, 1.0, MU, h)
        compiled = _slide_step(row, t, phi, w_r, 1.0, MU, h)
        assert (step.h_s > 0.0) is slides
        assert compiled[0] == step.ends and compiled[1] == pytest.approx(step.h_s, rel=1e-9, abs=1e-15)


@pytest.mark.parametrize("k", range(6))
def test_one_rod_slides_and_leaves_as_the_ode_ride_does(set_a: MillModel, k: int) -> None:
    # the paper's point 200/800 rpm, one rod from the bottom: solve_ivp (DOP853, rtol 1e-11) against the
    # event loop's Runge–Kutta slide steps; most cam phases slide back and never leave within the turn
    scene = _paper_point(set_a, 2.0 * math.pi * (k + 0.5) / 6)
    reference = ride(scene, "locked", friction=MU)
    t_end = 2.0 * math.pi / scene.omega_r_rad_s
    run = simulate(scene, t_end, friction=MU)
    if not reference.detached:
        assert run.detachments.size == 0
        return
    first = run.detachments[0]
    assert first["time_s"] == pytest.approx(reference.time_s, abs=1e-7)
    assert first["theta_rad"] == pytest.approx(reference.theta_rad, abs=1e-6)
    assert first["slid_s"] == pytest.approx(reference.slip_time_s, abs=1e-7)
    assert first["slid_s"] > 0.0


def test_without_friction_the_rods_are_carried(set_a: MillModel) -> None:
    scene = _paper_point(set_a, 1.0, rods=6)
    t_end = 2.0 * math.pi / scene.omega_r_rad_s
    carried = simulate(scene, t_end)
    assert np.all(carried.detachments["slid_s"] == 0.0)
    with_slip = simulate(scene, t_end, friction=MU)
    assert np.any(with_slip.detachments["slid_s"] > 0.0)
    compiled, _ = simulate_compiled(scene, t_end, friction=MU)
    assert first_difference(with_slip, compiled) is None
    np.testing.assert_allclose(compiled.detachments["slid_s"], with_slip.detachments["slid_s"], atol=1e-12)


def test_the_time_slid_inside_another_rod_is_summed_alike_in_both_engines(set_a: MillModel) -> None:
    # held rods are not tested against each other: sliding back they pass through each other to the bottom;
    # the run says how much of its sliding that is (overlap_s of slide_s)
    t_end = 2.0 * 2.0 * math.pi / (200.0 * RPM)
    six = _paper_point(set_a, 1.0, rods=6)
    reference = simulate(six, t_end, friction=MU)
    compiled, _ = simulate_compiled(six, t_end, friction=MU)
    assert reference.slide_s > 0.0 and 0.5 * reference.slide_s < reference.overlap_s <= reference.slide_s
    assert compiled.slide_s == pytest.approx(reference.slide_s, rel=1e-12)
    assert compiled.overlap_s == pytest.approx(reference.overlap_s, rel=1e-12)
    assert np.sum(reference.detachments["slid_s"]) <= reference.slide_s  # rods still sliding at the end count
    alone = simulate(_paper_point(set_a, 1.0), t_end, friction=MU)
    assert alone.slide_s > 0.0 and alone.overlap_s == 0.0  # nothing to be inside of
    carried = simulate_compiled(six, t_end)[0]
    assert carried.slide_s == 0.0 and carried.overlap_s == 0.0


def test_a_rod_that_slid_leaves_at_its_own_rate(set_a: MillModel) -> None:
    # the ODE ride's departure flown by slip_ride.fly_to_wall (eq. 10 from φ_d at φ̇_d) against the event loop
    scene = _paper_point(set_a, 2.0 * math.pi * 3.5 / 6)  # the phase that detaches (above)
    reference = ride(scene, "locked", friction=MU)
    assert reference.detached
    assert reference.theta_rate_rad_s < 0.9 * scene.omega_r_rad_s  # it fell behind the wall
    landing = fly_to_wall(scene, reference.time_s, reference.theta_rad, reference.theta_rate_rad_s)
    assert landing is not None
    t_end = 2.0 * math.pi / scene.omega_r_rad_s
    for run in (simulate(scene, t_end, friction=MU), simulate_compiled(scene, t_end, friction=MU)[0]):
        first = run.impacts[0]
        assert first["partner"] == -1
        assert first["flight_time_s"] == pytest.approx(landing.flight_time_s, rel=1e-5)
        assert first["normal_velocity_m_s"] == pytest.approx(landing.normal_velocity_m_s, rel=1e-4)


def test_a_slide_step_ends_where_it_detaches_or_regrips(set_a: MillModel) -> None:
    scene = _paper_point(set_a, 2.0 * math.pi * 3.5 / 6)
    w_r = scene.omega_r_rad_s
    onset = stick_slip_onset(scene, scene.theta0_rad, 0.0, 1.0, MU)
    assert 0.0 < onset < 1.0
    theta = scene.theta0_rad + w_r * onset
    s = slide_direction(scene, onset, theta)
    t, phi, rate, ends, steps = onset, theta, w_r, SLIDE_STEP, 0
    h = slide_step_s(scene)
    while ends == SLIDE_STEP and steps < 10_000:
        step = slide_step(scene, t, phi, rate, s, MU, h)
        t, phi, rate, ends, steps = t + step.h_s, step.theta_rad, step.rate_rad_s, step.ends, steps + 1
        assert 0.0 < step.h_s <= h
    assert ends in (DETACH, REGRIP)
    if ends == REGRIP:
        assert s * (rate - w_r) >= 0.0
    else:
        assert scene.model.r0_m * rate * rate - g_eff_m_s2(scene, t) * math.sin(phi) <= 0.0


@pytest.mark.parametrize("friction", [-0.1, math.nan])
def test_a_friction_that_is_not_a_coefficient_is_refused(set_a: MillModel, friction: float) -> None:
    scene = _paper_point(set_a, 1.0)
    with pytest.raises(PhysicsInputError, match="friction"):
        simulate(scene, 0.1, friction=friction)
    with pytest.raises(PhysicsInputError, match="friction"):
        simulate_compiled(scene, 0.1, friction=friction)
    with pytest.raises(ValueError, match="friction"):
        many_events(scene_row(scene), 0.1, friction=friction)


@pytest.mark.parametrize("steps", [0, -4, 2.5, True, "32"])
def test_a_slide_step_count_that_is_not_a_whole_number_is_refused(set_a: MillModel, steps: object) -> None:
    scene = _paper_point(set_a, 1.0)
    with pytest.raises(PhysicsInputError, match=r"slide_steps = .* whole number ≥ 1"):
        simulate(scene, 0.1, friction=MU, slide_steps=steps)  # type: ignore[arg-type]
    with pytest.raises(PhysicsInputError, match=r"slide_steps = .* whole number ≥ 1"):
        simulate_compiled(scene, 0.1, friction=MU, slide_steps=steps)  # type: ignore[arg-type]
    with pytest.raises(PhysicsInputError, match="slide_steps"):
        many_events(scene_row(scene), 0.1, friction=MU, slide_steps=steps)  # type: ignore[arg-type]


def test_the_slide_converges_at_fourth_order_in_both_engines(set_a: MillModel) -> None:
    # the phase that slides and leaves (above): its departure against solve_ivp's at 8, 16 and 32 steps a
    # scale; classical Runge–Kutta's error falls 16× a halving (more than 8× asked); both engines alike
    scene = _paper_point(set_a, 2.0 * math.pi * 3.5 / 6)
    reference = ride(scene, "locked", friction=MU)
    t_end = 2.0 * math.pi / scene.omega_r_rad_s
    errors = []
    for steps in (8, 16, 32):
        run = simulate(scene, t_end, friction=MU, slide_steps=steps)
        compiled, _ = simulate_compiled(scene, t_end, friction=MU, slide_steps=steps)
        assert first_difference(run, compiled) is None
        errors.append(abs(float(run.detachments[0]["time_s"]) - reference.time_s))
    assert errors[0] > 8.0 * errors[1] > 64.0 * errors[2] > 0.0
