"""An invalid speed measurement trips at once, without the debounce (docs/safety.md#measured-speed-interlock)."""

from __future__ import annotations

import math

import pytest

from millctl.config import MillConfig
from millctl.controller.monitor import MeasuredSpeedMonitor
from millctl.safety import Envelope


@pytest.mark.parametrize(
    ("omega_r_rpm", "omega_v_rpm"),
    [(math.nan, 300.0), (60.0, math.nan), (math.inf, 300.0), (60.0, -math.inf), (-10.0, 300.0), (60.0, -10.0)],
)
def test_an_invalid_measurement_trips_at_the_first_sample(
    config: MillConfig, omega_r_rpm: float, omega_v_rpm: float
) -> None:
    monitor = MeasuredSpeedMonitor(Envelope.from_config(config), config.interlock.debounce_samples)
    reason = monitor.update(omega_r_rpm, omega_v_rpm)
    assert reason is not None and reason.startswith("invalid speed measurement")


def test_noise_around_standstill_within_the_tolerance_is_valid(config: MillConfig) -> None:
    monitor = MeasuredSpeedMonitor(Envelope.from_config(config), config.interlock.debounce_samples)
    assert monitor.update(-0.5, -1.0) is None


def test_a_debounce_of_one_trips_at_the_first_sample_outside_and_none_is_refused(config: MillConfig) -> None:
    envelope = Envelope.from_config(config)
    with pytest.raises(ValueError, match=r"^debounce_samples = 0 must be ≥ 1$"):
        MeasuredSpeedMonitor(envelope, 0)
    monitor = MeasuredSpeedMonitor(envelope, 1)
    assert monitor.debounce_samples == 1 and monitor.outside_in_a_row == 0
    assert monitor.update(60.0, 300.0) is None
    reason = monitor.update(390.0, 300.0)  # far over the rotary limit at 300 rpm of vibration
    assert reason is not None and reason.startswith("measured speeds outside the envelope for 1 samples")
