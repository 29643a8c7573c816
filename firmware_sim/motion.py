"""What the node commands its drives: accepted setpoints, their re-check, and the controlled stop.

Every Setpoints frame is re-checked here (SAFETY.md item 12, defence in
depth) with the one limit module, :mod:`millctl.safety`: the envelope
(``Envelope.check``) and a rate bound per drive (:class:`~millctl.safety.slew.SlewBudget`),
so that a sender that bypasses the controller can neither jump nor walk the
setpoint faster than the drive's rate by sending more often. The node never
clamps: a refused frame changes nothing.

The controlled stop (stop category 1) is planned by the same
:class:`~millctl.safety.RampPlanner` as the controller's ramps, from the
present command, at the drives' maximum rates, ω_r first where the limit
falls with ω_v.
"""

from __future__ import annotations

from millctl.config.models import MillConfig
from millctl.protocol.messages import RefusalCode, Setpoints
from millctl.safety import STANDSTILL, Envelope, RampPlanner, SpeedPoint, Trajectory, Verdict
from millctl.safety.slew import SlewBudget

ACCEL_SLACK_FACTOR = 1.5
"""Accepted setpoints may move at most this many times the drive's max acceleration (rpm/s) over any window ..."""
ACCEL_SLACK_RPM = 0.2
"""... plus a burst of that rate × ``timing.watchdog_timeout_s`` and this much (rpm, two steps of the 0.1 rpm grid)."""
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
    """The node's commanded speed pair (rpm), the last accepted setpoint and its rate bound (times in s)."""

    def __init__(self, config: MillConfig, envelope: Envelope) -> None:
        self.envelope = envelope
        drives = config.drives
        self.max_accel_rpm_s = (drives.rotary.max_accel_rpm_s, drives.vibration.max_accel_rpm_s)
        self.slew = tuple(
            SlewBudget(
                rate_per_s=accel * ACCEL_SLACK_FACTOR,
                burst=accel * ACCEL_SLACK_FACTOR * config.timing.watchdog_timeout_s + ACCEL_SLACK_RPM,
            )
            for accel in self.max_accel_rpm_s
        )
        """The rate bound of (ω_r, ω_v): refills at 1.5 × max accel, holds at most its burst."""
        settle_s = STOP_SETTLE_TIME_CONSTANTS * max(drives.rotary.time_constant_s, drives.vibration.time_constant_s)
        self.planner = RampPlanner(envelope, settle_s=settle_s)
        self.accepted = STANDSTILL
        """The last accepted setpoint pair (rpm); standstill after boot, ARM, a stop or RESET."""
        self.stop: Trajectory | None = None
        """The controlled stop being followed, if any."""
        self.stop_started_s = 0.0

    def reset(self, now_s: float) -> None:
        """Forget setpoints and stops: command standstill from ``now_s``."""
        self.accepted = STANDSTILL
        self.stop = None
        for budget in self.slew:
            budget.refill(now_s)

    def check(self, setpoint: Setpoints, now_s: float) -> RefusalCode:
        """Re-check one setpoint frame: the envelope, then the step from the last accepted setpoint.

        Each drive's step must fit its :class:`SlewBudget`: over any window of
        length T the accepted setpoints move at most 1.5 × max accel × T plus
        a burst of 1.5 × max accel × ``timing.watchdog_timeout_s`` + 0.2 rpm,
        however many frames are sent. A sender that waits cannot bank more
        than the burst (the drives slew both axes at once; only small steps
        keep that path inside the envelope); one that sends more often gets no
        more.
        """
        furnace_c = setpoint.furnace_c if setpoint.heater_on else None
        verdict = self.envelope.check(setpoint.rotary_rpm, setpoint.vibration_rpm, furnace_c)
        code = refusal_code(verdict, self.envelope)
        if code is not RefusalCode.NONE:
            return code
        for step, budget in zip(self._steps(setpoint), self.slew, strict=True):
            if not budget.allows(step, now_s):
                return RefusalCode.ACCEL_LIMIT
        return RefusalCode.NONE

    def accept(self, setpoint: Setpoints, now_s: float) -> None:
        """Make a checked setpoint the command, its steps spent from the rate bound."""
        for step, budget in zip(self._steps(setpoint), self.slew, strict=True):
            budget.spend(step, now_s)
        self.accepted = SpeedPoint(setpoint.rotary_rpm, setpoint.vibration_rpm)

    def _steps(self, setpoint: Setpoints) -> tuple[float, float]:
        """The step of each drive (rpm) from the last accepted setpoint."""
        return (
            setpoint.rotary_rpm - self.accepted.omega_r_rpm,
            setpoint.vibration_rpm - self.accepted.omega_v_rpm,
        )

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
