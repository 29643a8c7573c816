"""Errata of eqs 8b and 9 as numbers for Set A (the closed forms live in limits.py)."""

from __future__ import annotations

import pytest

from millctl.config import LimitLaw, MillConfig
from millctl.physics.limits import (
    LimitParams,
    eq7_denominator,
    omega_r_max,
    sin_alpha_bound_consistent,
    sin_alpha_bound_printed_eq8b,
)
from millctl.units import rad_s_to_rpm, rpm_to_rad_s


@pytest.fixture(scope="module")
def p(config: MillConfig) -> LimitParams:
    return LimitParams.from_config(config)


def test_eq8b_consistent_bound(p: LimitParams) -> None:
    """Printed 8b gives −0.0027 (a length); eq. 7 bounds sin α < 1.64 at 800 rpm (denominator 0)."""
    w_v = rpm_to_rad_s(800.0)
    assert float(sin_alpha_bound_printed_eq8b(p, w_v)) == pytest.approx(-0.002685, abs=2e-6)
    bound = float(sin_alpha_bound_consistent(p, w_v))
    assert bound == pytest.approx(1.640, abs=1e-3)
    assert float(eq7_denominator(p, w_v, bound)) == pytest.approx(0.0, abs=1e-12)


def test_eq9_set_a_numbers(p: LimitParams) -> None:
    w_v = rpm_to_rad_s(800.0)
    got = {law: float(rad_s_to_rpm(omega_r_max(law, p, w_v))) for law in LimitLaw}
    assert got[LimitLaw.PAPER_EQ9] == pytest.approx(200.0, abs=0.1)
    assert got[LimitLaw.PAPER_EVERY_CYCLE] == pytest.approx(98.5, abs=0.1)
    assert got[LimitLaw.CORRECTED_EVERY_PHASE] == pytest.approx(118.9, abs=0.1)
    assert got[LimitLaw.CORRECTED_BEST_PHASE] == pytest.approx(292.0, abs=0.1)
