"""millctl.physics.roots.brentq against scipy.optimize.brentq: the same roots on the calls the engine makes.

The physics used scipy's brentq until issue 36 (part 5) replaced it by a plain-Python copy, so
that the node and the service start without importing scipy.optimize. These tests record every
root the reference engine asks for (detachment: N and N'; events: the separations) over a grid of
speeds in both variants and a few multi-rod simulations, and ask scipy the same question.
"""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from scipy import optimize

from millctl.config import ModelVariant
from millctl.physics import detachment, events, roots
from millctl.physics.model import MillModel, Scene
from millctl.physics.simulate import simulate
from millctl.physics.telemetry import revolution_summary
from millctl.units import rpm_to_rad_s

Call = tuple[Callable[[float], float], float, float, dict[str, Any], float]


@pytest.fixture
def recorded(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[Call]]:
    """Every brentq call of detachment.py and events.py: (f, a, b, keywords, the root ours returned)."""
    calls: list[Call] = []

    def recording(f: Callable[[float], float], a: float, b: float, **kw: Any) -> float:
        root = roots.brentq(f, a, b, **kw)
        calls.append((f, a, b, kw, root))
        return root

    monkeypatch.setattr(detachment, "brentq", recording)
    monkeypatch.setattr(events, "brentq", recording)
    yield calls


def _assert_scipy_agrees(calls: list[Call]) -> None:
    """Each recorded root is scipy's, to the last bit (the same loop in the same float64 arithmetic)."""
    assert len(calls) > 50, f"only {len(calls)} brentq calls: the comparison would say little"
    differ = [(a, b, ours, theirs) for f, a, b, kw, ours in calls if ours != (theirs := optimize.brentq(f, a, b, **kw))]
    assert differ == [], f"{len(differ)} of {len(calls)} roots differ from scipy's, e.g. {differ[:3]}"


@pytest.mark.parametrize("variant", [ModelVariant.CORRECTED, ModelVariant.PAPER])
def test_the_telemetry_roots_are_scipys(set_a: MillModel, variant: ModelVariant, recorded: list[Call]) -> None:
    model = dataclasses.replace(set_a, variant=variant)
    for rot_rpm in (2.0, 30.0, 75.0, 120.0, 150.0, 200.0, 260.0):
        for vib_rpm in (0.0, 400.0, 800.0, 1000.0, 1400.0):
            revolution_summary(model, rpm_to_rad_s(rot_rpm), rpm_to_rad_s(vib_rpm), engine="reference")
    _assert_scipy_agrees(recorded)


def test_the_many_rod_roots_are_scipys(set_a_corrected: MillModel, recorded: list[Call]) -> None:
    for rot_rpm, vib_rpm in ((150.0, 800.0), (100.0, 1200.0)):
        w_r = rpm_to_rad_s(rot_rpm)
        simulate(Scene(model=set_a_corrected, omega_r_rad_s=w_r, omega_v_rad_s=rpm_to_rad_s(vib_rpm)), math.pi / w_r)
    _assert_scipy_agrees(recorded)


def _outcome(solver: Callable[..., float], f: Callable[[float], float], a: float, b: float, **kw: Any) -> object:
    """The root, or "no convergence" when the solver ran out of iterations (a RuntimeError in both)."""
    try:
        return solver(f, a, b, **kw)
    except RuntimeError:
        return "no convergence"


def test_textbook_roots_match_scipy_bit_for_bit() -> None:
    cases: list[tuple[Callable[[float], float], float, float]] = [
        (lambda x: x * x - 2.0, 0.0, 2.0),
        (lambda x: math.cos(x) - x, 0.0, 1.0),
        (lambda x: x**3, -1.0, 0.5),  # a triple root: bisection-dominated, > 100 iterations to 1e-300
        (lambda x: math.exp(x) - 1e-300, -800.0, 0.0),
        (lambda x: math.tanh(50.0 * (x - 0.3)), -1.0, 1.0),
    ]
    outcomes = []
    for f, a, b in cases:
        for xtol in (2e-12, 1e-300):
            for maxiter in (100, 2000):
                ours = _outcome(roots.brentq, f, a, b, xtol=xtol, maxiter=maxiter)
                assert ours == _outcome(optimize.brentq, f, a, b, xtol=xtol, maxiter=maxiter), (a, b, xtol, maxiter)
                outcomes.append(ours)
    assert outcomes.count("no convergence") == 2  # the triple root at maxiter 100: both give up alike


def test_an_end_that_is_a_root_is_returned() -> None:
    assert roots.brentq(lambda x: x, 0.0, 1.0) == 0.0
    assert roots.brentq(lambda x: x - 1.0, 0.0, 1.0) == 1.0


def test_refusals_name_the_value() -> None:
    with pytest.raises(ValueError, match=r"f\(0.0\) = 1.0 and f\(1.0\) = 2.0 have one sign"):
        roots.brentq(lambda x: x + 1.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="is NaN"):
        roots.brentq(lambda x: math.nan if x > 0.25 else -1.0, 0.0, 1.0)
    with pytest.raises(ValueError, match=r"xtol = 0\.0 must be > 0"):
        roots.brentq(lambda x: x - 0.5, 0.0, 1.0, xtol=0.0)
    with pytest.raises(ValueError, match=r"rtol = 1e-16 must be >= 4·eps"):
        roots.brentq(lambda x: x - 0.5, 0.0, 1.0, rtol=1e-16)
    with pytest.raises(roots.RootNotConverged, match="maxiter = 3"):
        roots.brentq(lambda x: x**3, -1.0, 0.5, xtol=1e-300, maxiter=3)
    with pytest.raises(RuntimeError):  # as scipy's, for callers that catch that
        optimize.brentq(lambda x: x**3, -1.0, 0.5, xtol=1e-300, maxiter=3)


def test_the_node_and_the_service_start_without_scipy_optimize() -> None:
    probe = (
        "import sys\nimport firmware_sim.__main__, firmware_sim.embedded, millctl.service.server\n"
        "print(sorted(m for m in sys.modules if m.startswith(('scipy.optimize', 'canopen'))))"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True)
    assert done.stdout.strip().splitlines()[-1] == "[]"
