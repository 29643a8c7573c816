"""The node's measured-speed checks (SAFETY.md item 6, node side): envelope, over-speed, stall, sensor.

Run once per node tick on the sensor readings. Every threshold comes from
the configuration; the few factors below say how many of a configured
quantity make a threshold, and are documented in docs/operations.md.

* ENVELOPE: ``Envelope.check_measured`` (the configured measurement
  tolerance allowed) outside for ``interlock.debounce_samples`` ticks in a row.
* OVERSPEED: a reading above the drive's ``max_speed_rpm`` + tolerance, as
  many ticks in a row.
* STALL: the node's reference model says the drive turns faster than
  ``STALL_MIN_TOLERANCES`` × tolerance while the sensor reads ≤ tolerance,
  for ``STALL_TIME_CONSTANTS`` × the drive's time constant.
* SENSOR: a non-finite reading at once; a jump between consecutive readings
  that the drive cannot make (more than max_accel·dt + ``JUMP_SIGMAS`` ×
  its configured noise + tolerance), or a turning drive whose noisy sensor
  repeats the identical value, for ``debounce_samples`` ticks in a row.
"""

from __future__ import annotations

import math

from millctl.config.models import Drive, MillConfig
from millctl.protocol.messages import NO_FAULTS, FaultFlag
from millctl.safety import Envelope

STALL_MIN_TOLERANCES = 5.0
"""A drive counts as commanded to turn when its reference speed exceeds this many tolerances."""
STALL_TIME_CONSTANTS = 5.0
"""How long (in the drive's time constants) a commanded drive may read ≈ 0 before STALL."""
JUMP_SIGMAS = 6.0
"""Sensor noise standard deviations allowed in a jump between consecutive readings."""


class _AxisCheck:
    """Stall and sensor plausibility of one drive."""

    def __init__(self, drive: Drive, tolerance_rpm: float, debounce: int) -> None:
        self.drive = drive
        self.tolerance_rpm = tolerance_rpm
        self.debounce = debounce
        self.previous_rpm: float | None = None
        self.implausible = 0
        self.stuck = 0
        self.stalled_s = 0.0

    def check(self, measured_rpm: float, reference_rpm: float, dt_s: float) -> FaultFlag:
        drive, tol = self.drive, self.tolerance_rpm
        faults = NO_FAULTS
        if not math.isfinite(measured_rpm):
            self.previous_rpm = None
            return FaultFlag.SENSOR
        if self.previous_rpm is not None and dt_s > 0.0:
            step = abs(measured_rpm - self.previous_rpm)
            bound = drive.max_accel_rpm_s * dt_s + JUMP_SIGMAS * drive.speed_noise_rpm + tol
            self.implausible = self.implausible + 1 if step > bound else 0
            repeated = step == 0.0 and drive.speed_noise_rpm > 0.0 and measured_rpm > tol
            self.stuck = self.stuck + 1 if repeated else 0
        self.previous_rpm = measured_rpm
        if self.implausible >= self.debounce or self.stuck >= self.debounce:
            faults |= FaultFlag.SENSOR
        commanded = reference_rpm > STALL_MIN_TOLERANCES * tol
        self.stalled_s = self.stalled_s + dt_s if commanded and measured_rpm <= tol else 0.0
        if self.stalled_s >= STALL_TIME_CONSTANTS * drive.time_constant_s:
            faults |= FaultFlag.STALL
        return faults


class SpeedMonitor:
    """Checks the measured speed pair every tick and reports the faults it sees (not latched here)."""

    def __init__(self, config: MillConfig, envelope: Envelope) -> None:
        self.envelope = envelope
        self.debounce = config.interlock.debounce_samples
        tol = config.interlock.measurement_tolerance_rpm
        self.tolerance_rpm = tol
        self.rotary = _AxisCheck(config.drives.rotary, tol, self.debounce)
        self.vibration = _AxisCheck(config.drives.vibration, tol, self.debounce)
        self.outside = 0
        """Consecutive ticks with the measured pair outside the envelope."""
        self.overspeed = 0

    def check(self, measured: tuple[float, float], reference: tuple[float, float], dt_s: float) -> FaultFlag:
        """Faults seen in this tick's readings (rpm) against the reference speeds (rpm)."""
        m_r, m_v = measured
        faults = self.rotary.check(m_r, reference[0], dt_s) | self.vibration.check(m_v, reference[1], dt_s)
        if not (math.isfinite(m_r) and math.isfinite(m_v)):
            return faults | FaultFlag.SENSOR
        self.outside = 0 if self.envelope.allows_measured(m_r, m_v) else self.outside + 1
        if self.outside >= self.debounce:
            faults |= FaultFlag.ENVELOPE
        over = (
            m_r > self.rotary.drive.max_speed_rpm + self.tolerance_rpm
            or m_v > self.vibration.drive.max_speed_rpm + self.tolerance_rpm
        )
        self.overspeed = self.overspeed + 1 if over else 0
        if self.overspeed >= self.debounce:
            faults |= FaultFlag.OVERSPEED
        return faults


__all__ = ["JUMP_SIGMAS", "STALL_MIN_TOLERANCES", "STALL_TIME_CONSTANTS", "SpeedMonitor"]
