"""The paper's fixed-step schemes: observed convergence order and their interface."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from millctl.errors import PhysicsInputError
from millctl.physics.agreement import random_scenes
from millctl.physics.legacy import arc_wall_sink_m
from millctl.physics.methods import METHODS, Method, first_impact
from millctl.physics.model import MillModel, Scene

DTS = (4e-4, 2e-4, 1e-4, 5e-5)


@pytest.fixture(scope="module")
def scenes(set_a_corrected: MillModel) -> list[Scene]:
    model = dataclasses.replace(set_a_corrected, n_rods=1)
    return [Scene(model, 15.0 + 0.7 * k, 80.0, -0.5 * math.pi, 0.3 + 0.9 * k) for k in range(6)]


def _observed_order(scenes: list[Scene], method: Method) -> tuple[float, list[float]]:
    refs = [first_impact(s) for s in scenes]
    errors = []
    for dt in DTS:
        errs = []
        for scene, ref in zip(scenes, refs, strict=True):
            event = first_impact(scene, method, dt=dt)
            assert event is not None and ref is not None and event.partner == ref.partner
            errs.append(abs(event.time_s - ref.time_s))
        errors.append(float(np.mean(errs)))
    return float(np.polyfit(np.log(DTS), np.log(errors), 1)[0]), errors


def test_paper_scheme_is_first_order(scenes: list[Scene]) -> None:
    """End-point averaging: mean time error ∝ dt (observed order ≈ 1)."""
    order, errors = _observed_order(scenes, "legacy")
    assert 0.8 < order < 1.4, errors
    assert errors[-1] < DTS[-1]


def test_linear_interpolation_is_second_order(scenes: list[Scene]) -> None:
    order, errors = _observed_order(scenes, "legacy-interp")
    assert 1.6 < order < 2.4, errors


def test_arcs_wall_approaches_the_circle(scenes: list[Scene]) -> None:
    """q arcs: the rod can sink between two points by at most arc_wall_sink_m (≈ π² r_v r0/(2 r_r q²))."""
    scene = scenes[0]
    ref = first_impact(scene)
    assert ref is not None
    for q in (36, 360):
        event = first_impact(scene, "legacy-arcs", dt=1e-5, q=q)
        assert event is not None and event.partner == -1
        m = scene.model
        sag_m = arc_wall_sink_m(m, q)
        assert abs(event.time_s - ref.time_s) <= 1e-5 + sag_m / max(ref.normal_velocity_m_s, 1e-3)


@pytest.mark.parametrize("method", METHODS)
def test_every_method_answers_the_same_question(scenes: list[Scene], method: Method) -> None:
    event = first_impact(scenes[1], method, dt=1e-5, tol=1e-9)
    ref = first_impact(scenes[1])
    assert event is not None and ref is not None
    assert (event.rod, event.partner) == (ref.rod, ref.partner)
    assert event.time_s == pytest.approx(ref.time_s, abs=2e-5)
    assert event.method == method


@pytest.mark.parametrize(
    ("method", "kwargs"),
    [
        ("legacy", {}),
        ("legacy", {"dt": 0.0}),
        ("legacy", {"dt": -1e-3}),
        ("legacy-arcs", {"dt": 1e-4, "q": 2}),
        ("ivp", {"tol": 0.0}),
        ("euler", {}),
    ],
)
def test_bad_method_arguments_rejected(scenes: list[Scene], method: str, kwargs: dict[str, float]) -> None:
    with pytest.raises(PhysicsInputError):
        first_impact(scenes[0], method, **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("omega_r", "omega_v", "theta0", "alpha0", "r_d"),
    [
        (2.3129430531764954, 6.466186880254966, -2.571021636988274, 1.923302260323237, 0.0),
        (6.047744319868955, 120.56946550733613, -2.89535834200271, 3.5458380217554706, 0.0012453445347168338),
    ],
    ids=["rd0", "rd1.2mm"],
)
def test_rod_rod_energy_uses_the_held_partner_whichever_rod_of_the_pair_flies(
    set_a_corrected: MillModel, omega_r: float, omega_v: float, theta0: float, alpha0: float, r_d: float
) -> None:
    """A flying rod hitting a rod still on the wall has m_eff = m, in the paper's scheme too.

    Found by the benchmark: the scheme looked at the lower-numbered rod of the pair, which
    here is the flying one, and booked m/2 (an energy error of exactly one half).
    """
    model = dataclasses.replace(set_a_corrected, eccentricity_m=r_d)
    scene = Scene(model, omega_r, omega_v, theta0, alpha0)
    exact = first_impact(scene, "exact")
    legacy = first_impact(scene, "legacy", dt=1e-5)
    assert exact is not None and legacy is not None
    assert {exact.rod, exact.partner} == {legacy.rod, legacy.partner} and legacy.partner >= 0
    assert legacy.energy_j == pytest.approx(exact.energy_j, rel=1e-3)


@pytest.mark.parametrize("dt", [1e-4, 1e-5])
def test_compiled_paper_scheme_is_the_numpy_one(set_a_corrected: MillModel, dt: float) -> None:
    """``legacy-compiled`` (the like-for-like baseline, issue 17) gives ``legacy``'s answer on six-rod scenes."""
    for scene in random_scenes(set_a_corrected, 12, 5):
        numpy_event = first_impact(scene, "legacy", dt=dt)
        compiled = first_impact(scene, "legacy-compiled", dt=dt)
        assert (numpy_event is None) == (compiled is None)
        if numpy_event is None or compiled is None:
            continue
        assert (compiled.rod, compiled.partner) == (numpy_event.rod, numpy_event.partner)
        assert compiled.time_s == pytest.approx(numpy_event.time_s, abs=1e-12)
        assert compiled.energy_j == pytest.approx(numpy_event.energy_j, rel=1e-9, abs=1e-30)
        assert compiled.x_m == pytest.approx(numpy_event.x_m, abs=1e-12)


def test_compiled_paper_scheme_rejects_a_bad_step(scenes: list[Scene]) -> None:
    with pytest.raises(PhysicsInputError, match=r"dt = 0\.0 s"):
        first_impact(scenes[0], "legacy-compiled", dt=0.0)
    with pytest.raises(PhysicsInputError, match="needs a time step"):
        first_impact(scenes[0], "legacy-compiled")
