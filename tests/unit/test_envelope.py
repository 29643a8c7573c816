"""The interlock envelope: refusals name value, limit and law; scalar and vectorised agree."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from millctl.config import LimitLaw, MillConfig
from millctl.safety import Envelope, InterlockRefused


@pytest.fixture(scope="module")
def envelope(config: MillConfig) -> Envelope:
    return Envelope.from_config(config)


def test_paper_operating_point(envelope: Envelope) -> None:
    assert envelope.check(180.0, 800.0).ok
    verdict = envelope.check(250.0, 800.0)
    assert not verdict.ok
    reason = verdict.reason()
    assert "250.0 rpm" in reason and "190.0 rpm" in reason and "paper-eq9" in reason
    assert verdict.margin_rpm == pytest.approx(190.0 - 250.0, abs=0.1)


def test_standstill_is_always_inside(envelope: Envelope) -> None:
    for w_v in (0.0, 500.0, 1200.0):
        assert envelope.check(0.0, w_v).ok


def test_refuses_not_clamps(envelope: Envelope) -> None:
    with pytest.raises(InterlockRefused) as info:
        envelope.require(300.0, 800.0)
    assert info.value.verdict.refusals[0].quantity == "omega_r"
    assert "docs/safety.md" in str(info.value)


@pytest.mark.parametrize(
    ("w_r", "w_v", "t", "quantity"),
    [
        (-1.0, 100.0, None, "omega_r"),
        (math.nan, 100.0, None, "omega_r"),
        (10.0, 5000.0, None, "omega_v"),
        (10.0, 100.0, 2000.0, "furnace_temp"),
    ],
)
def test_absolute_limits(envelope: Envelope, w_r: float, w_v: float, t: float | None, quantity: str) -> None:
    verdict = envelope.check(w_r, w_v, t)
    assert quantity in [r.quantity for r in verdict.refusals]


def test_no_real_limit_allows_only_standstill(config: MillConfig) -> None:
    env = Envelope.from_config(config, law=LimitLaw.CORRECTED_EVERY_PHASE)
    verdict = env.check(1.0, 1100.0)
    assert not verdict.ok and "only standstill" in verdict.reason()
    assert env.check(0.0, 1100.0).ok


def test_rates(envelope: Envelope) -> None:
    assert envelope.check_rates(10.0, 50.0).ok
    assert not envelope.check_rates(1000.0, 50.0).ok
    assert not envelope.check_rates(0.0, 50.0).ok
    assert envelope.check_heating_rate(10.0).ok
    assert not envelope.check_heating_rate(100.0).ok


@settings(max_examples=300)
@given(
    st.sampled_from(list(LimitLaw)),
    st.floats(-10.0, 500.0, allow_nan=False),
    st.floats(0.0, 1500.0, allow_nan=False),
)
def test_scalar_check_agrees_with_vectorised_limits(config: MillConfig, law: LimitLaw, w_r: float, w_v: float) -> None:
    env = Envelope.from_config(config, law=law)
    inside = env.check(w_r, w_v).ok
    assert inside == bool(env.contains(np.array([w_r]), np.array([w_v]))[0])
    limit = float(env.omega_r_limit_rpm(w_v))
    if w_r > 0 and w_v <= env.vibration_max_rpm:
        assert inside == (w_r <= limit)
