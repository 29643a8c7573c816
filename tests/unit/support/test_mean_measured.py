"""The steady-window judgement of the hil scenarios: the mean of distinct readings, not one noisy reading."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.hil.scenario_support import mean_measured_rpm


def status(rotary_rpm: float, vibration_rpm: float) -> dict[str, Any]:
    return {"measured_rotary_rpm": rotary_rpm, "measured_vibration_rpm": vibration_rpm}


def test_a_repeated_telemetry_frame_counts_once() -> None:
    # Four statuses, two readings: the status poll outruns the 50 Hz telemetry.
    window = [status(60.0, 300.0), status(60.0, 300.0), status(60.0, 300.0), status(62.0, 304.0)]
    assert mean_measured_rpm(window) == (61.0, 302.0)


def test_a_reading_that_returns_after_another_counts_again() -> None:
    window = [status(60.0, 300.0), status(61.0, 301.0), status(60.0, 300.0)]
    assert mean_measured_rpm(window) == pytest.approx((60 + 1 / 3, 300 + 1 / 3))


def test_a_drive_holding_its_speed_is_judged_inside_the_tolerance_though_single_readings_are_not() -> None:
    # The vibration sensor's noise (σ = 1 rpm, config/mill.toml) against the 3 rpm tolerance: over many
    # windows of 50 readings (1 s of DriveTelemetry) some single readings fall outside, no mean does.
    rng = np.random.default_rng(20261128)
    readings = 300.0 + rng.normal(0.0, 1.0, size=(400, 50))
    assert (np.abs(readings - 300.0) > 3.0).any()
    means = [mean_measured_rpm([status(60.0, float(v)) for v in row])[1] for row in readings]
    assert max(abs(m - 300.0) for m in means) < 1.0


def test_a_drive_off_its_speed_is_seen_in_the_mean() -> None:
    rng = np.random.default_rng(7)
    window = [status(60.0, float(v)) for v in 296.0 + rng.normal(0.0, 1.0, size=50)]
    assert mean_measured_rpm(window)[1] == pytest.approx(296.0, abs=0.5)


def test_an_empty_window_is_an_error() -> None:
    with pytest.raises(ValueError, match="no statuses"):
        mean_measured_rpm([])
