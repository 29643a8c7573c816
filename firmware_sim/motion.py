"""What the node commands its drives: accepted setpoints, their re-check, and the controlled stop.

Every Setpoints frame is re-checked here (SAFETY.md item 12, defence in
depth) with the one limit module, :mod:`millctl.safety`: the envelope
(``Envelope.check``) and a step limit per drive, so that a sender that
bypasses the controller cannot jump. The node never clamps: a refused frame
changes nothing.

The controlled stop (stop category 1) is planned by the same
:class:`~millctl.safety.RampPlanner` as the controller's ramps, from the
present command, at the drives' maximum rates, ω_r first where the limit
falls with ω_v.
"""

from __future__ import annotations

from millctl.config.models import MillConfig
from millctl.protocol.messages import RefusalCode, Setpoints
from millctl.safety import STANDSTILL, Envelope, RampPlanner, SpeedPoint, Trajectory, Verdict

ACCEL_SLACK_FACTOR = 1.5
"""A setpoint step may be this many times the drive's max acceleration × the elapsed time ..."""
ACCEL_SLACK_RPM = 0.2
"""... plus this much (rpm, two steps of the wire's 0.1 rpm resolution)."""
STOP_SETTLE_TIME_CONSTANTS = 3.0
"""Dwell after each axis of the stop, in the slower drive's time constants, so the lagging drive follows."""


def refusal_code(verdict: Verdict, envelope: Envelope) -> RefusalCode:
    """The NodeStatus refusal code for an envelope verdict (NONE when inside)."""
    if verdict.ok:
        return RefusalCode.NONE
    quantities = {r.quantity for r in verdict.refusals}
    if "omega_r" in quantities and verdict.omega_r_limit_rpm < envelope.rotary_max_rpm:
        return RefusalCode.ENVELOPE
    if quantities & {"omega_r", "omega_v"}:
        return RefusalCode.SPEED_LIMIT
    return RefusalCode.TEMP_LIMIT


class Motion:
    """The node's commanded speed pair (rpm) and the last accepted setpoint (times in s)."""

    def __init__(self, config: MillConfig, envelope: Envelope) -> None:
        self.envelope = envelope
        self._timing = config.timing
        drives = config.drives
        self.max_accel_rpm_s = (drives.rotary.max_accel_rpm_s, drives.vibration.max_accel_rpm_s)
        settle_s = STOP_SETTLE_TIME_CONSTANTS * max(drives.rotary.time_constant_s, drives.vibration.time_constant_s)
        self.planner = RampPlanner(envelope, settle_s=settle_s)
        self.accepted = STANDSTILL
        """The last accepted setpoint pair (rpm); standstill after boot, ARM, a stop or RESET."""
        self.accepted_at_s = 0.0
        self.stop: Trajectory | None = None
        """The controlled stop being followed, if any."""
        self.stop_started_s = 0.0

    def reset(self, now_s: float) -> None:
        """Forget setpoints and stops: command standstill from ``now_s``."""
        self.accepted = STANDSTILL
        self.accepted_at_s = now_s
        self.stop = None

    def check(self, setpoint: Setpoints, now_s: float) -> RefusalCode:
        """Re-check one setpoint frame: the envelope, then the step from the last accepted setpoint.

        The elapsed time in the step limit is max(time since the last accepted
        setpoint, ``timing.setpoint_period_s``), capped at
        ``timing.watchdog_timeout_s`` so that a sender that waits cannot bank
        a large step (the drives slew both axes at once; only small steps
        keep that path inside the envelope).
        """
        furnace_c = setpoint.furnace_c if setpoint.heater_on else None
        verdict = self.envelope.check(setpoint.rotary_rpm, setpoint.vibration_rpm, furnace_c)
        code = refusal_code(verdict, self.envelope)
        if code is not RefusalCode.NONE:
            return code
        timing = self._timing
        elapsed_s = min(max(now_s - self.accepted_at_s, timing.setpoint_period_s), timing.watchdog_timeout_s)
        steps = (
            abs(setpoint.rotary_rpm - self.accepted.omega_r_rpm),
            abs(setpoint.vibration_rpm - self.accepted.omega_v_rpm),
        )
        for step, accel in zip(steps, self.max_accel_rpm_s, strict=True):
            if step > accel * elapsed_s * ACCEL_SLACK_FACTOR + ACCEL_SLACK_RPM:
                return RefusalCode.ACCEL_LIMIT
        return RefusalCode.NONE

    def accept(self, setpoint: Setpoints, now_s: float) -> None:
        """Make a checked setpoint the command."""
        self.accepted = SpeedPoint(setpoint.rotary_rpm, setpoint.vibration_rpm)
        self.accepted_at_s = now_s

    def begin_stop(self, now_s: float) -> None:
        """Plan the controlled stop from the present command (kept if one is already under way)."""
        if self.stop is not None:
            return
        self.stop = self.planner.plan_stop(self.command(now_s))
        self.stop_started_s = now_s

    def command(self, now_s: float) -> SpeedPoint:
        """The speed pair commanded to the drives at ``now_s`` (rpm)."""
        if self.stop is not None:
            return self.stop.at(now_s - self.stop_started_s)
        return self.accepted

    def stop_done(self, now_s: float) -> bool:
        """True when no stop is under way or it has reached standstill."""
        return self.stop is None or now_s - self.stop_started_s >= self.stop.duration_s

    @property
    def zero(self) -> bool:
        """True when the accepted setpoint is standstill and no stop is under way."""
        return self.stop is None and self.accepted == STANDSTILL


__all__ = ["ACCEL_SLACK_FACTOR", "ACCEL_SLACK_RPM", "STOP_SETTLE_TIME_CONSTANTS", "Motion", "refusal_code"]
