"""The interlock envelope: refusals name value, limit and law; scalar and vectorised agree."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from millctl.config import LimitLaw, MillConfig
from millctl.physics.limits import is_every_cycle_bound
from millctl.safety import Envelope, InterlockRefused
from millctl.safety.envelope import Refusal, Verdict
from millctl.units import rpm_to_rad_s


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


@settings(max_examples=300, deadline=None)  # a loaded machine (or a mutant run) must not fail it on time
@given(
    st.sampled_from(list(LimitLaw)),
    st.floats(-10.0, 500.0, allow_nan=False),
    st.floats(0.0, 1500.0, allow_nan=False),
)
# the hard cases, every run: standstill, −0, the drives' limits, and a law that allows only standstill there
@example(LimitLaw.PAPER_EQ9, 0.0, 0.0)
@example(LimitLaw.PAPER_EQ9, -0.0, 800.0)
@example(LimitLaw.PAPER_EQ9, 400.0, 1200.0)
@example(LimitLaw.PAPER_EQ9, 0.1, 1200.0)
@example(LimitLaw.CORRECTED_EVERY_PHASE, 1.0, 1100.0)
def test_scalar_check_agrees_with_vectorised_limits(config: MillConfig, law: LimitLaw, w_r: float, w_v: float) -> None:
    env = Envelope.from_config(config, law=law)
    inside = env.check(w_r, w_v).ok
    assert inside == bool(env.contains(np.array([w_r]), np.array([w_v]))[0])
    limit = float(env.omega_r_limit_rpm(w_v))
    if w_r > 0 and w_v <= env.vibration_max_rpm:
        assert inside == (w_r <= limit)


def test_the_description_names_law_equation_and_margin(envelope: Envelope, config: MillConfig) -> None:
    assert envelope.description == "paper-eq9 (paper eq. 9), margin 5%"
    corrected = Envelope.from_config(config, law=LimitLaw.CORRECTED_BEST_PHASE)
    assert corrected.law is LimitLaw.CORRECTED_BEST_PHASE
    assert corrected.description == "corrected-best-phase (corrected law, best phase), margin 5%"


def test_from_config_takes_every_bound_from_the_configuration(config: MillConfig) -> None:
    # built here: the module's fixture is built once, for the first test, and mutmut credits from_config to that
    # test alone, so it did not run this one on from_config's mutants (run 26, docs/safety.md)
    envelope = Envelope.from_config(config)
    drives, furnace, interlock = config.drives, config.furnace, config.interlock
    assert (envelope.law, envelope.margin) == (interlock.law, interlock.margin)
    assert (envelope.rotary_max_rpm, envelope.vibration_max_rpm) == (
        drives.rotary.max_speed_rpm,
        drives.vibration.max_speed_rpm,
    )
    assert (envelope.rotary_max_accel_rpm_s, envelope.vibration_max_accel_rpm_s) == (
        drives.rotary.max_accel_rpm_s,
        drives.vibration.max_accel_rpm_s,
    )
    assert (envelope.furnace_min_c, envelope.furnace_max_c) == (furnace.min_setpoint_c, furnace.max_setpoint_c)
    assert envelope.max_heating_rate_c_per_min == furnace.max_heating_rate_c_per_min
    assert envelope.measurement_tolerance_rpm == interlock.measurement_tolerance_rpm


def test_the_limit_is_the_margin_below_the_law_and_never_above_the_drive(envelope: Envelope) -> None:
    for w_v in (0.0, 400.0, 800.0, 1200.0):
        law_rpm = float(envelope.law_limit_rpm(w_v))
        assert float(envelope.omega_r_limit_rpm(w_v)) == pytest.approx(0.95 * law_rpm, rel=1e-12)
        assert envelope.limit_rpm(w_v) == pytest.approx(0.95 * law_rpm, rel=1e-12)
    assert float(envelope.law_limit_rpm(800.0)) == pytest.approx(199.97, abs=0.01)  # Set A, paper eq. 9
    slow_drive = dataclasses.replace(envelope, rotary_max_rpm=150.0)
    assert float(slow_drive.omega_r_limit_rpm(900.0)) == 150.0 and slow_drive.limit_rpm(900.0) == 150.0
    assert slow_drive.limit_rpm(0.0) == pytest.approx(0.95 * float(envelope.law_limit_rpm(0.0)))


def test_every_cycle_is_the_physics_verdict_at_the_speed_in_rad_s(envelope: Envelope) -> None:
    speeds_rpm = np.array([100.0, 200.0, 400.0, 1100.0])
    expected = is_every_cycle_bound(envelope.law, envelope.params, rpm_to_rad_s(speeds_rpm))
    assert list(envelope.every_cycle(speeds_rpm)) == list(expected) == [True, True, False, False]


def test_a_negative_or_non_finite_speed_is_refused_naming_each(envelope: Envelope) -> None:
    verdict = envelope.check(-1.0, math.inf)
    assert verdict.refusals == (
        Refusal("omega_r", -1.0, 0.0, "rpm", "omega_r = -1.0 rpm must be a finite speed ≥ 0"),
        Refusal("omega_v", math.inf, 0.0, "rpm", "omega_v = inf rpm must be a finite speed ≥ 0"),
    )
    assert (verdict.omega_r_limit_rpm, verdict.margin_rpm) == (0.0, -math.inf)
    assert (
        verdict.reason()
        == "omega_r = -1.0 rpm must be a finite speed ≥ 0; omega_v = inf rpm must be a finite speed ≥ 0"
    )
    assert [r.quantity for r in envelope.check(10.0, -0.5).refusals] == ["omega_v"]


def test_a_vibration_speed_over_the_drive_is_refused_with_its_limit(envelope: Envelope) -> None:
    (refusal,) = envelope.check(0.0, 1200.5).refusals
    assert refusal == Refusal(
        "omega_v",
        1200.5,
        1200.0,
        "rpm",
        "ω_v = 1200.5 rpm exceeds the vibration drive's absolute limit 1200.0 rpm (drives.vibration.max_speed_rpm)",
    )
    assert envelope.check(0.0, 1200.0).ok
    assert envelope.check(0.0, 1202.9, tolerance_rpm=3.0).ok
    assert not envelope.check(0.0, 1203.1, tolerance_rpm=3.0).ok


def test_a_rotary_speed_over_the_law_names_value_limit_law_and_margin(envelope: Envelope) -> None:
    law_rpm = float(envelope.law_limit_rpm(800.0))
    limit = envelope.limit_rpm(800.0)
    verdict = envelope.check(250.0, 800.0)
    assert verdict.refusals == (
        Refusal(
            "omega_r",
            250.0,
            limit,
            "rpm",
            f"ω_r = 250.0 rpm exceeds the limit {limit:.1f} rpm at ω_v = 800.0 rpm "
            f"(0.95 × {law_rpm:.1f} rpm, paper-eq9 (paper eq. 9), margin 5%)",
        ),
    )
    assert (verdict.omega_r_limit_rpm, verdict.margin_rpm) == (limit, limit - 250.0)
    inside = envelope.check(180.0, 800.0)
    assert inside.ok and (inside.omega_r_limit_rpm, inside.margin_rpm) == (limit, limit - 180.0)


def test_a_rotary_speed_a_hair_over_the_limit_shows_three_digits(envelope: Envelope) -> None:
    limit = envelope.limit_rpm(800.0)
    (refusal,) = envelope.check(limit + 0.002, 800.0).refusals
    assert refusal.reason.startswith(f"ω_r = {limit + 0.002:.3f} rpm exceeds the limit {limit:.3f} rpm at ω_v")
    assert envelope.check(limit, 800.0).ok


def test_the_rotary_drives_own_limit_is_named_when_it_binds(envelope: Envelope) -> None:
    slow_drive = dataclasses.replace(envelope, rotary_max_rpm=150.0)
    (refusal,) = slow_drive.check(150.5, 900.0).refusals
    assert refusal.reason == (
        "ω_r = 150.5 rpm exceeds the rotary drive's absolute limit 150.0 rpm (drives.rotary.max_speed_rpm)"
    )
    assert refusal.limit == 150.0
    assert slow_drive.check(150.0, 900.0).ok


def test_where_the_law_gives_no_limit_the_reason_says_only_standstill(config: MillConfig) -> None:
    env = Envelope.from_config(config, law=LimitLaw.CORRECTED_EVERY_PHASE)
    (refusal,) = env.check(1.0, 1100.0).refusals
    assert refusal.reason == (
        "ω_r = 1.0 rpm exceeds no real limit at ω_v = 1100.0 rpm under corrected-every-phase "
        "(corrected law, every phase), margin 5%: only standstill is allowed"
    )


def test_a_rotary_speed_within_the_tolerance_passes_a_measured_check(envelope: Envelope) -> None:
    limit = envelope.limit_rpm(800.0)
    assert envelope.check(limit + 2.9, 800.0, tolerance_rpm=3.0).ok
    assert not envelope.check(limit + 3.1, 800.0, tolerance_rpm=3.0).ok
    assert envelope.check_measured(limit + 2.9, 800.0).ok
    assert not envelope.check_measured(limit + 3.1, 800.0).ok
    assert envelope.allows_measured(limit + 2.9, 800.0)
    assert not envelope.allows_measured(limit + 3.1, 800.0)


@pytest.mark.parametrize(("temp_c", "bound"), [(19.9, 20.0), (900.1, 900.0)])
def test_a_furnace_setpoint_outside_its_range_is_refused_naming_the_bound(
    envelope: Envelope, temp_c: float, bound: float
) -> None:
    (refusal,) = envelope.check(0.0, 0.0, temp_c).refusals
    assert refusal == Refusal(
        "furnace_temp",
        temp_c,
        bound,
        "°C",
        f"furnace setpoint {temp_c:.1f} °C is outside [20.0, 900.0] °C (furnace.min/max_setpoint_c)",
    )
    assert envelope.check(0.0, 0.0, 20.0).ok and envelope.check(0.0, 0.0, 900.0).ok


def test_require_returns_the_verdict_or_raises_with_the_reason_and_where_to_read(envelope: Envelope) -> None:
    verdict = envelope.require(100.0, 800.0, 300.0)
    assert verdict.ok and verdict.omega_r_limit_rpm == envelope.limit_rpm(800.0)
    with pytest.raises(InterlockRefused) as info:
        envelope.require(100.0, 800.0, 1000.0)
    assert str(info.value) == (
        "setpoint refused by the interlock: furnace setpoint 1000.0 °C is outside [20.0, 900.0] °C "
        "(furnace.min/max_setpoint_c) (see docs/safety.md#setpoint-interlock)"
    )
    assert (
        str(InterlockRefused(Verdict(), what="ramp"))
        == "ramp refused by the interlock:  (see docs/safety.md#setpoint-interlock)"
    )


def test_a_refusal_reads_as_its_reason_and_a_verdict_joins_them() -> None:
    first = Refusal("omega_r", 1.0, 0.0, "rpm", "first")
    assert str(first) == "first"
    assert Verdict((first, Refusal("omega_v", 1.0, 0.0, "rpm", "second"))).reason() == "first; second"
    assert Verdict().ok and Verdict().reason() == "" and Verdict().margin_rpm == math.inf


def test_rates_at_and_past_each_drives_acceleration(envelope: Envelope) -> None:
    assert envelope.check_rates(40.0, 120.0).ok
    (rotary,) = envelope.check_rates(40.1, 120.0).refusals
    assert rotary == Refusal(
        "omega_r_rate",
        40.1,
        40.0,
        "rpm/s",
        "omega_r_rate = 40.1 rpm/s exceeds 40.0 rpm/s (drives.rotary.max_accel_rpm_s)",
    )
    (vibration,) = envelope.check_rates(40.0, 120.1).refusals
    assert vibration.reason == "omega_v_rate = 120.1 rpm/s exceeds 120.0 rpm/s (drives.vibration.max_accel_rpm_s)"
    assert vibration.limit == 120.0
    both = envelope.check_rates(math.nan, -1.0).refusals
    assert [r.reason for r in both] == [
        "omega_r_rate = nan rpm/s must be a finite rate > 0",
        "omega_v_rate = -1.0 rpm/s must be a finite rate > 0",
    ]
    assert [(r.quantity, r.limit, r.unit) for r in both] == [
        ("omega_r_rate", 40.0, "rpm/s"),
        ("omega_v_rate", 120.0, "rpm/s"),
    ]
    assert [r.value for r in envelope.check_rates(0.0, -1.0).refusals] == [0.0, -1.0]  # each refusal names its value
    assert not envelope.check_rates(10.0, math.inf).ok


def test_the_heating_rate_at_and_past_its_maximum(envelope: Envelope) -> None:
    assert envelope.check_heating_rate(20.0).ok and envelope.check_heating_rate(0.01).ok
    for rate in (20.01, 0.0, -1.0, math.nan, math.inf):
        (refusal,) = envelope.check_heating_rate(rate).refusals
        assert refusal == Refusal(
            "heating_rate",
            rate,
            20.0,
            "°C/min",
            f"heating rate {rate} °C/min must be in (0, 20.0] (furnace.max_heating_rate_c_per_min)",
        ) or math.isnan(rate)
    assert envelope.check_heating_rate(math.nan).refusals[0].reason.startswith("heating rate nan °C/min")


@pytest.mark.parametrize("law", list(LimitLaw))
def test_allows_is_the_verdict_of_check_on_a_grid_with_and_without_tolerance(config: MillConfig, law: LimitLaw) -> None:
    env = Envelope.from_config(config, law=law)
    speeds_v = [-1.0, 0.0, 300.0, 900.0, 1100.0, 1199.0, 1200.0, 1201.0, 1203.5, math.nan]
    for w_v in speeds_v:
        limit = env.limit_rpm(w_v) if math.isfinite(w_v) and w_v >= 0.0 else 0.0
        for w_r in (-0.5, 0.0, 0.5, limit, limit + 2.0, limit + 4.0, 500.0, math.inf):
            for tolerance in (0.0, 3.0):
                verdict = env.check(w_r, w_v, tolerance_rpm=tolerance)
                assert env.allows(w_r, w_v, tolerance) == verdict.ok, (w_r, w_v, tolerance)
                assert bool(env.contains(w_r, w_v, tolerance)) == verdict.ok, (w_r, w_v, tolerance)


def test_the_scalar_inside_test_has_no_tolerance_unless_given(envelope: Envelope) -> None:
    limit = envelope.limit_rpm(800.0)
    assert not envelope.allows(limit + 0.5, 800.0)
    assert envelope.allows(limit + 0.5, 800.0, tolerance_rpm=1.0)
    assert envelope.allows(limit, 800.0)


def test_the_scalar_inside_test_allows_only_standstill_where_the_law_gives_no_real_limit(config: MillConfig) -> None:
    """Above ~995 rpm the rods detach every cycle at any ω_r under the paper's worst-phase law: ω_r ≤ 0."""
    envelope = Envelope.from_config(config, law=LimitLaw.PAPER_EVERY_CYCLE)
    assert envelope.limit_rpm(1100.0) <= 0.0
    assert envelope.allows(0.0, 1100.0)
    assert not envelope.allows(1.0, 1100.0)
    assert not envelope.allows(0.1, 1100.0)
