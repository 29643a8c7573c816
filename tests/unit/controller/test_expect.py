"""The stop ceiling starts from the highest of what was commanded and what was measured (controller.expect)."""

from __future__ import annotations

import pytest

from millctl.config import MillConfig
from millctl.controller.expect import SpeedExpectation
from millctl.safety import Envelope, RampPlanner, SpeedPoint

TOL = 3.0


@pytest.fixture
def expectation(config: MillConfig) -> SpeedExpectation:
    expect = SpeedExpectation(RampPlanner(Envelope.from_config(config)), TOL, 2.0, 3)
    expect.commanded(0.0, SpeedPoint(100.0, 400.0))
    expect.commanded(1.0, SpeedPoint(100.0, 400.0))
    return expect


def ceiling_at_start(expect: SpeedExpectation, measured: tuple[float, float] | None) -> tuple[float, float]:
    expect.begin_stop(1.0, measured)
    (_, r_high), (_, v_high) = expect.band(1.0)
    return r_high - TOL, v_high - TOL


def test_a_stop_ceiling_starts_from_what_was_commanded_when_the_drives_are_slower(
    expectation: SpeedExpectation,
) -> None:
    assert ceiling_at_start(expectation, (50.0, 200.0)) == pytest.approx((100.0, 400.0))


def test_a_stop_ceiling_starts_from_what_was_measured_when_the_drives_are_faster(expectation: SpeedExpectation) -> None:
    """A runaway drive is stopped from where it is, not from where it was told to be."""
    assert ceiling_at_start(expectation, (150.0, 500.0)) == pytest.approx((150.0, 500.0))


def test_a_stop_ceiling_with_nothing_measured_starts_from_what_was_commanded(expectation: SpeedExpectation) -> None:
    assert ceiling_at_start(expectation, None) == pytest.approx((100.0, 400.0))
