"""The node's measured-speed checks, tick by tick at their bounds (firmware_sim/monitor.py, SAFETY.md item 6).

Each check is driven straight through :class:`SpeedMonitor` with readings
chosen at its threshold: one reading on the bound is not a fault, one past it
is, and a fault needs ``interlock.debounce_samples`` ticks in a row (3 in
the default configuration). Set A: rotary drive 400 rpm, 40 rpm/s, τ 0.2 s,
noise 0.5 rpm; vibration drive 1200 rpm, noise 1.0 rpm; tolerance 3 rpm.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import pytest

from firmware_sim.monitor import JUMP_SIGMAS, STALL_MIN_TOLERANCES, STALL_TIME_CONSTANTS, SpeedMonitor
from millctl.config import MillConfig
from millctl.protocol.messages import NO_FAULTS, FaultFlag
from millctl.safety import Envelope

DT_S = 0.25
"""A tick long enough that the bounds below are exact in binary floating point."""


@pytest.fixture
def monitor(config: MillConfig) -> SpeedMonitor:
    return SpeedMonitor(config, Envelope.from_config(config))


def feed(
    monitor: SpeedMonitor, readings: Iterable[tuple[float, float]], reference: tuple[float, float] = (0.0, 0.0)
) -> list[FaultFlag]:
    """The faults reported at each tick for the measured pairs (rpm) against one reference pair (rpm)."""
    return [monitor.check(reading, reference, DT_S) for reading in readings]


def jump_bound_rpm(config: MillConfig) -> float:
    rotary = config.drives.rotary
    return (
        rotary.max_accel_rpm_s * DT_S
        + JUMP_SIGMAS * rotary.speed_noise_rpm
        + config.interlock.measurement_tolerance_rpm
    )


def test_the_set_a_figures_these_tests_are_built_on(config: MillConfig) -> None:
    assert config.interlock.debounce_samples == 3
    assert config.interlock.measurement_tolerance_rpm == 3.0
    assert jump_bound_rpm(config) == 16.0  # 40 rpm/s × 0.25 s + 6 × 0.5 rpm + 3 rpm


def test_a_non_finite_reading_is_a_sensor_fault_at_once(monitor: SpeedMonitor) -> None:
    assert feed(monitor, [(math.nan, 0.0)]) == [FaultFlag.SENSOR]
    assert feed(monitor, [(0.0, math.inf)]) == [FaultFlag.SENSOR]
    assert monitor.outside == 0  # an unreadable pair is not judged against the envelope


def test_a_reading_after_a_non_finite_one_is_not_judged_as_a_jump(monitor: SpeedMonitor) -> None:
    flags = feed(monitor, [(100.0, 0.0), (math.nan, 0.0), (0.0, 0.0), (0.5, 0.0), (0.0, 0.0)])
    assert flags[2:] == [NO_FAULTS] * 3
    assert monitor.rotary.implausible == 0


def test_a_jump_past_what_the_drive_can_do_is_a_sensor_fault_after_debounce(config: MillConfig) -> None:
    bound = jump_bound_rpm(config)
    on_bound = SpeedMonitor(config, Envelope.from_config(config))
    assert feed(on_bound, [(0.0, 0.0), (bound, 0.0)] * 3) == [NO_FAULTS] * 6
    past = SpeedMonitor(config, Envelope.from_config(config))
    flags = feed(past, [(0.0, 0.0), (bound + 0.5, 0.0), (0.0, 0.0), (bound + 0.5, 0.0)])
    assert flags == [NO_FAULTS, NO_FAULTS, NO_FAULTS, FaultFlag.SENSOR]
    assert past.rotary.implausible == 3


def test_a_plausible_reading_restarts_the_jump_count(config: MillConfig) -> None:
    bound = jump_bound_rpm(config)
    monitor = SpeedMonitor(config, Envelope.from_config(config))
    flags = feed(monitor, [(0.0, 0.0), (bound + 0.5, 0.0), (0.0, 0.0), (0.5, 0.0), (bound + 1.0, 0.0), (0.0, 0.0)])
    assert flags == [NO_FAULTS] * 6
    assert monitor.rotary.implausible == 2


def test_no_jump_is_judged_over_a_zero_tick(monitor: SpeedMonitor) -> None:
    monitor.check((0.0, 0.0), (0.0, 0.0), DT_S)
    for _ in range(4):
        assert monitor.check((300.0, 0.0), (0.0, 0.0), 0.0) == NO_FAULTS
        assert monitor.check((0.5, 0.0), (0.0, 0.0), 0.0) == NO_FAULTS
    assert monitor.rotary.implausible == 0


def test_a_turning_noisy_sensor_repeating_its_value_is_stuck(monitor: SpeedMonitor) -> None:
    assert feed(monitor, [(0.0, 60.0)] * 4) == [NO_FAULTS] * 3 + [FaultFlag.SENSOR]
    assert monitor.vibration.stuck == 3


def test_a_sensor_at_rest_may_repeat_its_value(monitor: SpeedMonitor, config: MillConfig) -> None:
    tolerance = config.interlock.measurement_tolerance_rpm
    assert feed(monitor, [(tolerance, tolerance)] * 5) == [NO_FAULTS] * 5
    assert (monitor.rotary.stuck, monitor.vibration.stuck) == (0, 0)


def test_a_sensor_without_noise_may_repeat_its_value(config: MillConfig) -> None:
    drives = config.drives.model_copy(
        update={"rotary": config.drives.rotary.model_copy(update={"speed_noise_rpm": 0.0})}
    )
    quiet = config.model_copy(update={"drives": drives})
    monitor = SpeedMonitor(quiet, Envelope.from_config(quiet))
    assert feed(monitor, [(60.0, 0.0)] * 5) == [NO_FAULTS] * 5


def test_a_value_that_moves_restarts_the_stuck_count(monitor: SpeedMonitor) -> None:
    flags = feed(monitor, [(0.0, 60.0), (0.0, 60.0), (0.0, 60.0), (0.0, 60.5), (0.0, 60.5), (0.0, 60.5)])
    assert flags == [NO_FAULTS] * 6
    assert monitor.vibration.stuck == 2


def test_a_commanded_drive_reading_standstill_stalls_after_five_time_constants(
    monitor: SpeedMonitor, config: MillConfig
) -> None:
    tolerance = config.interlock.measurement_tolerance_rpm
    commanded = STALL_MIN_TOLERANCES * tolerance + 0.5
    ticks = round(STALL_TIME_CONSTANTS * config.drives.rotary.time_constant_s / DT_S)
    assert ticks == 4
    readings = [(tolerance, 0.0), (tolerance - 0.5, 0.0)] * 2
    flags = feed(monitor, readings, reference=(commanded, 0.0))
    assert flags == [NO_FAULTS] * 3 + [FaultFlag.STALL]
    assert monitor.rotary.stalled_s == pytest.approx(1.0)


def test_a_reference_on_the_threshold_is_not_a_command_to_turn(monitor: SpeedMonitor, config: MillConfig) -> None:
    threshold = STALL_MIN_TOLERANCES * config.interlock.measurement_tolerance_rpm
    assert feed(monitor, [(0.0, 0.0), (0.5, 0.0)] * 4, reference=(threshold, 0.0)) == [NO_FAULTS] * 8
    assert monitor.rotary.stalled_s == 0.0


def test_a_reading_above_the_tolerance_restarts_the_stall_time(monitor: SpeedMonitor, config: MillConfig) -> None:
    tolerance = config.interlock.measurement_tolerance_rpm
    readings = [(0.0, 0.0), (0.5, 0.0), (0.0, 0.0), (tolerance + 0.5, 0.0), (0.0, 0.0), (0.5, 0.0), (0.0, 0.0)]
    assert feed(monitor, readings, reference=(100.0, 0.0)) == [NO_FAULTS] * 7
    assert monitor.rotary.stalled_s == pytest.approx(0.75)


def test_the_vibration_drive_stalls_on_its_own_time_constant(monitor: SpeedMonitor, config: MillConfig) -> None:
    ticks = math.ceil(STALL_TIME_CONSTANTS * config.drives.vibration.time_constant_s / DT_S)  # 0.75 s: 3 ticks
    flags = feed(monitor, [(0.0, 0.0), (0.0, 0.5)] * 2, reference=(0.0, 100.0))
    assert flags == [NO_FAULTS] * (ticks - 1) + [FaultFlag.STALL] * (4 - ticks + 1)


def envelope_edge(envelope: Envelope, tolerance_rpm: float, omega_v_rpm: float, past_rpm: float) -> tuple[float, float]:
    """The measured pair ``past_rpm`` beyond the envelope's rotary limit with the tolerance, at ω_v (rpm)."""
    rotary_rpm = envelope.limit_rpm(omega_v_rpm) + tolerance_rpm + past_rpm
    assert rotary_rpm + 1.0 < envelope.rotary_max_rpm  # under the drive's maximum: only the envelope is crossed
    return rotary_rpm, omega_v_rpm


def test_a_measured_pair_outside_the_envelope_is_a_fault_after_debounce(
    monitor: SpeedMonitor, config: MillConfig
) -> None:
    tolerance = config.interlock.measurement_tolerance_rpm

    def edge(omega_v_rpm: float, past_rpm: float) -> tuple[float, float]:
        return envelope_edge(monitor.envelope, tolerance, omega_v_rpm, past_rpm)

    on_edge = [edge(900.0, 0.0), edge(899.0, 0.0)]  # both axes move a little: not a stuck sensor
    assert feed(monitor, on_edge * 2) == [NO_FAULTS] * 4
    flags = feed(monitor, [edge(900.0, 0.5), edge(899.0, 0.0), edge(900.0, 0.5), edge(899.0, 0.5), edge(900.0, 0.5)])
    assert flags == [NO_FAULTS] * 4 + [FaultFlag.ENVELOPE]
    assert monitor.outside == 3


def test_overspeed_needs_a_reading_past_the_drives_maximum_and_tolerance_debounced(
    monitor: SpeedMonitor, config: MillConfig
) -> None:
    ceiling = config.drives.vibration.max_speed_rpm + config.interlock.measurement_tolerance_rpm
    on = [(0.0, ceiling), (0.0, ceiling - 0.5)] * 2
    assert all(FaultFlag.OVERSPEED not in flags for flags in feed(monitor, on))
    past = [(0.0, ceiling + 0.5), (0.0, ceiling + 1.0), (0.0, ceiling + 0.5)]
    assert [FaultFlag.OVERSPEED in flags for flags in feed(monitor, past)] == [False, False, True]


def test_rotary_overspeed_is_checked_too(monitor: SpeedMonitor, config: MillConfig) -> None:
    ceiling = config.drives.rotary.max_speed_rpm + config.interlock.measurement_tolerance_rpm
    on = [(ceiling, 0.0), (ceiling - 0.5, 0.0)] * 2
    assert all(FaultFlag.OVERSPEED not in flags for flags in feed(monitor, on))
    past = [(ceiling + 0.5, 0.0), (ceiling + 1.0, 0.0), (ceiling + 0.5, 0.0), (ceiling, 0.0)]
    assert [FaultFlag.OVERSPEED in flags for flags in feed(monitor, past)] == [False, False, True, False]
