"""The controller: makes the mill do what the operator asks, and never what the interlock forbids.

It owns the heartbeat (its counter advanced by :meth:`Controller.tick`, the
control loop itself, so a hung controller stops the heartbeat), tracks every
node frame with its age, and applies the interlock through
:mod:`millctl.safety`: setpoints outside the envelope are refused, moves are
planned ramps inside it, measured speeds are checked each tick, stale
telemetry and node faults trip, and trips latch until :meth:`Controller.reset`.
Steppable with an injected clock: :meth:`tick` never sleeps.

This module is the operator's commands and the control loop; the state and
the shared acts are :mod:`.core`'s, the judging of the node's reports
:mod:`.node_reports`', the furnace :mod:`.furnace_commands`' (one class, split
by concern).
"""

from __future__ import annotations

import logging
import math

from millctl.controller.confirm import Pending
from millctl.controller.core import RESET_TIMEOUT_S, STANDSTILL_RPM, CommandRefused
from millctl.controller.events import EventKind
from millctl.controller.furnace_commands import FurnaceCommands
from millctl.controller.node_reports import NodeReports
from millctl.controller.states import ControllerState
from millctl.controller.status import Status, build_status
from millctl.drives.base import LimitsState
from millctl.protocol import (
    CommandCode,
    DriveTelemetry,
    EStopSource,
    FurnaceTelemetry,
    NodeStatus,
)
from millctl.protocol import ControllerState as WireState
from millctl.protocol.bus_health import BusCondition
from millctl.safety import STANDSTILL, InterlockRefused, SpeedPoint, Trajectory
from millctl.safety.commands import Operation

log = logging.getLogger(__name__)

S = ControllerState

_WIRE_STATE = {
    S.DISCONNECTED: WireState.INIT,
    S.DISABLED: WireState.IDLE,
    S.ARMED: WireState.ARMED,
    S.RUNNING: WireState.RUNNING,
    S.STOPPING: WireState.STOPPING,
    S.TRIPPED: WireState.TRIPPED,
}


class Controller(FurnaceCommands, NodeReports):
    """The mill's controller on one bus, stepped by :meth:`tick`."""

    def status(self) -> Status:
        """A snapshot of everything an operator needs to see."""
        return build_status(self)

    def arm(self, source: str = "operator") -> None:
        """Ask the node to arm (from DISABLED, with a live heartbeat)."""
        self._require(Operation.ARM, "arm", source)
        self.drives.prepare_move(None)
        if self.drives.limits_state() is LimitsState.READY:
            self._command(CommandCode.ARM, source, "operator request")
            return
        self._arm_source = source  # sent once the drives hold their limits (SAFETY 28)
        self._emit(EventKind.COMMAND, source, "arm: the drives' limits are being written and read back first")

    def disarm(self, source: str = "operator") -> None:
        """Ask the node to disarm (from ARMED at standstill)."""
        self._require(Operation.DISARM, "disarm", source)
        if self.commanded != STANDSTILL or self.trajectory is not None:
            self._refuse(source, "disarm needs both setpoints at 0: stop first")
        self._disarm_pending = True
        self._command(CommandCode.DISARM, source, "operator request")

    def set_speeds(
        self,
        rotary_rpm: float,
        vibration_rpm: float,
        *,
        rotary_rate_rpm_s: float | None = None,
        vibration_rate_rpm_s: float | None = None,
        linear: bool = False,
        furnace_c: float | None = None,
        heating_rate_c_per_min: float | None = None,
        source: str = "operator",
    ) -> Trajectory:
        """Plan a ramp to new speeds (and, with ``furnace_c``, a furnace target) and start it.

        All or nothing: every part is checked before any is applied, so a
        refused furnace target leaves the speeds untouched and the other way
        round (InterlockRefused, nothing sent).
        """
        self._require(Operation.SET, "set speeds", source)
        if self._disarm_pending:  # the node disarms at rest and then refuses every setpoint: never drop a ramp
            self._refuse(source, "set speeds is not possible while a DISARM is pending: "
                         "arm again once the node reports DISABLED")
        furnace = self._furnace_part(furnace_c, heating_rate_c_per_min, source)
        target = SpeedPoint(rotary_rpm, vibration_rpm)
        try:
            if linear:
                move = self.planner.plan_linear(self.commanded, target, rotary_rate_rpm_s, vibration_rate_rpm_s)
            else:
                move = self.planner.plan(self.commanded, target, rotary_rate_rpm_s, vibration_rate_rpm_s)
        except InterlockRefused as refused:
            self._emit(EventKind.REFUSAL, source, str(refused), rotary_rpm=rotary_rpm, vibration_rpm=vibration_rpm)
            raise
        self.drives.prepare_move(move)
        self.trajectory = move
        self._trajectory_start_s = self.clock.now()
        self._limits_hold = self.drives.limits_state() is not LimitsState.READY
        self._emit(
            EventKind.COMMAND,
            source,
            f"ramp to ω_r = {move.end.omega_r_rpm:.1f} rpm, ω_v = {move.end.omega_v_rpm:.1f} rpm "
            f"over {move.duration_s:.1f} s",
            rotary_rpm=move.end.omega_r_rpm,
            vibration_rpm=move.end.omega_v_rpm,
            duration_s=move.duration_s,
        )
        if furnace is not None:
            self._apply_furnace(*furnace, source)
        return move

    def stop(self, source: str = "operator", reason: str = "operator request") -> None:
        """Controlled stop (category 1): the node ramps both drives down inside the envelope, heater off."""
        self._require(Operation.STOP, "stop", source)
        self._begin_stop(source, reason)

    def estop(self, source: str = "operator") -> None:
        """Emergency stop: the E-stop frame at the highest priority, repeated until the node reports it; a trip."""
        self.drives.estop(EStopSource.OPERATOR if source != "controller" else EStopSource.CONTROLLER)
        self._estop_pending = True
        self._estop_sent_s = self.clock.now()
        self._emit(EventKind.COMMAND, source, "E-STOP")
        self._trip(f"E-stop by {source}", source)

    def tick(self) -> None:
        """One control step: read the bus, check everything, advance the ramp, send what is due."""
        now = self.clock.now()
        dt = max(now - self._last_tick_s, 0.0)
        self._last_tick_s = now
        self._drain(now)
        self._check(now)
        self._advance(now, dt)
        self._transmit(now)

    def _drain(self, now: float) -> None:
        """Read every frame waiting (SAFETY 22); bad input is counted by the reader, never raised (SAFETY 19)."""
        batch = self.drives.drain(now)
        for error_frame in batch.error_frames:
            self._on_bus_condition(self.bus_health.on_error_frame(error_frame))
        self._on_bus_condition(self.bus_health.poll())
        # an E-stop from anyone is the node's to act on; it reports it in NodeStatus and we trip on that
        for decoded in batch.decoded:
            message = self.tracker.accept(decoded, now)
            if message is not None:
                self.tracker.connected(now)
            if isinstance(message, NodeStatus):
                self._on_node_status(message)
            elif isinstance(message, DriveTelemetry):
                self._on_measured(message)
            elif isinstance(message, FurnaceTelemetry):
                self._on_furnace(message)

    def _on_bus_condition(self, condition: BusCondition | None) -> None:
        """A change of the CAN controller's condition: an event; bus-off trips (docs/protocol.md#bus-errors)."""
        if condition is None:
            return
        health = self.bus_health.health
        cause = health.last_error or health.state_source
        self._emit(EventKind.BUS, "bus", f"CAN controller {condition}: {cause}", condition=condition.value,
                   tx_error_counter=health.tx_error_counter, rx_error_counter=health.rx_error_counter)
        if condition is BusCondition.BUS_OFF:
            bus = self.config.bus
            self._trip(
                f"CAN bus-off on {bus.interface}:{bus.channel} ({cause}): the controller cannot send, the node's "
                "watchdog stops the mill; check wiring, termination and bitrate (docs/protocol.md#bus-errors)",
                "bus",
            )

    def _check(self, now: float) -> None:
        if self.state is S.DISCONNECTED:
            return
        if self._reset_pending and now > self._reset_until_s:
            self._reset_pending = False
            node = self.node_status
            shown = f"{node.state.name}, last refusal {node.last_refusal.name}" if node else "unknown"
            self._emit(
                EventKind.REFUSAL,
                self._reset_source,
                f"reset did not complete within {RESET_TIMEOUT_S:.0f} s: node {shown}; clear the cause and retry",
            )
        stale = self.tracker.stale(now)
        if stale:
            self._node_state = None  # the node's history is lost: judge it afresh when it speaks again
        problems = stale + self.tracker.link_faults()
        if problems and self.state is not S.TRIPPED:
            self._trip("; ".join(problems))
        self._confirm_or_escalate(now)

    def _confirm_or_escalate(self, now: float) -> None:
        """Repeat what the node has not confirmed; escalate what it did not confirm in time; STOPPING's deadline."""
        for pending in self.confirmations.due(now):
            self.drives.command(pending.code)
            self.confirmations.sent(pending.code, pending.source, pending.reason, now)
            log.info("%s not yet confirmed by the node: sent again (%d)", pending.code.name, pending.sends)
        for pending in self.confirmations.expired(now):
            self._lost(pending)
        if self._estop_pending and now - self._estop_sent_s >= self.confirmations.repeat_s:
            self._send_estop()  # until the node reports it
        if self.state is S.STOPPING and now > self.expectation.stop_end_s:
            measured = self.measured
            shown = "unknown" if measured is None else f"{measured.rotary_rpm:.1f}/{measured.vibration_rpm:.1f} rpm"
            node = self._node_state.name if self._node_state else "unknown"
            self._escalate(
                f"controlled stop not complete by its deadline ({self.expectation.stop_bound_s:.1f} s: the planned "
                f"stop plus {self.expectation.window_s:.1f} s; node {node}, measured {shown})"
            )

    def _lost(self, pending: Pending) -> None:
        """A command the node did not confirm within the bound: STOP → E-stop; any other → a trip naming it."""
        node = self.node_status
        shown = f"{node.state.name}, last refusal {node.last_refusal.name}" if node else "silent"
        what = (
            f"{pending.code.name} ({pending.reason}) not confirmed by the node within "
            f"{self.config.interlock.command_confirm_s:.1f} s after {pending.sends} send(s) "
            f"(node {shown}; interlock.command_confirm_s)"
        )
        if pending.code is CommandCode.STOP:
            self._escalate(what)
        elif self.state is S.TRIPPED:
            if self._reset_pending:
                self._reset_pending = False
                self._emit(EventKind.REFUSAL, self._reset_source, f"reset did not complete: {what}; clear the cause "
                           "and retry")
        else:
            self._trip(what, "controller")

    def _advance(self, now: float, dt: float) -> None:
        if self._arm_source is not None:
            self._arm_when_limits_hold()
        if self.trajectory is not None and self._limits_hold:
            self._hold_for_limits(now)
        if self.trajectory is not None:
            elapsed = now - self._trajectory_start_s
            self.commanded = self.trajectory.at(elapsed)
            if elapsed >= self.trajectory.duration_s:
                self.commanded = self.trajectory.end
                self.trajectory = None
        self.expectation.commanded(now, self.commanded)
        if self.furnace_target_c is not None:
            step = self.heating_rate_c_per_min / 60.0 * dt
            delta = self.furnace_target_c - self.furnace_setpoint_c
            self.furnace_setpoint_c += math.copysign(min(abs(delta), step), delta)
        self.furnace_expectation.commanded(now, self._furnace_command())

    def _arm_when_limits_hold(self) -> None:
        """Send the waiting ARM once the drives hold their limits; refuse it when a drive does not."""
        verdict, source = self.drives.limits_state(), self._arm_source or "operator"
        if verdict is LimitsState.PENDING and self.state is S.DISABLED:
            return
        self._arm_source = None
        if self.state is not S.DISABLED:
            return  # a trip or a lost node overtook it: the ARM is void
        if verdict is LimitsState.REFUSED:
            self._emit(EventKind.REFUSAL, source, f"arm refused: {self.drives.limits_error}")
            return
        self._command(CommandCode.ARM, source, "operator request")

    def _hold_for_limits(self, now: float) -> None:
        """Keep the trajectory at its start until the drives hold its limits; a refusal trips (SAFETY 28)."""
        verdict = self.drives.limits_state()
        if verdict is LimitsState.PENDING:
            self._trajectory_start_s = now
            return
        self._limits_hold = False
        if verdict is LimitsState.REFUSED:
            self._trip(f"move refused: {self.drives.limits_error}", "drives")

    def _transmit(self, now: float) -> None:
        if now >= self._next_heartbeat_s:
            node = self.node_status  # echo its latest challenge: the node's proof this heartbeat is live
            self.drives.heartbeat(_WIRE_STATE[self.state], node.challenge if node is not None else 0)
            self._next_heartbeat_s = max(self._next_heartbeat_s + self.config.timing.heartbeat_period_s, now)
        if now >= self._next_setpoints_s:
            self._next_setpoints_s = max(self._next_setpoints_s + self.config.timing.setpoint_period_s, now)
            if self.state in (S.ARMED, S.RUNNING):
                furnace_c = self._furnace_command()
                snapped = self.planner.snap(self.commanded)
                self.run_orders.setpoints_sent(now, snapped != STANDSTILL, self._node_state)
                self.drives.setpoints(
                    snapped, self.config.furnace.ambient_temp_c if furnace_c is None else furnace_c,
                    furnace_c is not None,
                )
        self.drives.periodic(now)


__all__ = ["RESET_TIMEOUT_S", "STANDSTILL_RPM", "CommandRefused", "Controller"]
