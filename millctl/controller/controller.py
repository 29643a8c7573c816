"""The controller: makes the mill do what the operator asks, and never what the interlock forbids.

It owns the heartbeat (its counter advanced by :meth:`Controller.tick`, the
control loop itself, so a hung controller stops the heartbeat), tracks every
node frame with its age, and applies the interlock through
:mod:`millctl.safety`: setpoints outside the envelope are refused, moves are
planned ramps inside it, measured speeds are checked each tick, stale
telemetry and node faults trip, and trips latch until :meth:`Controller.reset`.
Steppable with an injected clock: :meth:`tick` never sleeps.
"""

from __future__ import annotations

import logging
import math

import can

from millctl.clock import Clock
from millctl.config.models import MillConfig
from millctl.controller.confirm import Confirmations, Pending
from millctl.controller.events import Event, EventKind, EventListener
from millctl.controller.expect import SpeedExpectation
from millctl.controller.furnace_expect import FurnaceExpectation
from millctl.controller.monitor import MeasuredSpeedMonitor
from millctl.controller.overtake import RunOrders
from millctl.controller.states import ControllerState, StateMachine, Transition
from millctl.controller.status import Status, build_status
from millctl.controller.tracking import TelemetryTracker
from millctl.drives.base import DrivesBackend, LimitsState
from millctl.drives.millbus import MillbusDrives
from millctl.drives.registry import open_drives
from millctl.errors import InterlockError, InvalidInputError
from millctl.protocol import (
    Codec,
    CommandCode,
    DriveTelemetry,
    EStopSource,
    FaultCode,
    FaultFlag,
    FurnaceTelemetry,
    NodeState,
    NodeStatus,
    default_codec,
)
from millctl.protocol import ControllerState as WireState
from millctl.protocol.bus_health import BusCondition, BusHealthMonitor
from millctl.safety import STANDSTILL, Envelope, InterlockRefused, RampPlanner, SpeedPoint, Trajectory
from millctl.safety.commands import CONTROLLER_ALLOWS, Operation, node_change_commanded

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

STANDSTILL_RPM = 1.0
"""Measured speeds below this count as standstill (rpm)."""

RESET_TIMEOUT_S = 2.0
"""A reset the node has not completed within this time is given up, with its reason (s)."""


class CommandRefused(InterlockError):
    """A command that the current state does not allow; nothing was sent."""


class Controller:
    """The mill's controller on one bus, stepped by :meth:`tick`."""

    def __init__(
        self,
        config: MillConfig,
        bus: can.BusABC,
        clock: Clock,
        *,
        codec: Codec | None = None,
        listener: EventListener | None = None,
        drives: DrivesBackend | None = None,
    ) -> None:
        self.config = config
        self.bus = bus
        self.clock = clock
        self.codec = codec or default_codec()
        self.listener = listener
        self.envelope = Envelope.from_config(config)
        self.drives: DrivesBackend = (
            drives if drives is not None else open_drives(config, bus, self.codec, self.envelope)
        )
        """The drives, through the one boundary the backends share (:mod:`millctl.drives.base`)."""
        self.planner = RampPlanner.from_config(config, self.envelope)
        self.machine = StateMachine(clock.now, self._on_transition)
        self.tracker = TelemetryTracker(
            self.codec, config.interlock, e2e=self.drives.e2e, furnace=self.drives.has_furnace
        )
        self.reader = self.drives.reader
        self.bus_health = BusHealthMonitor(bus, config.bus.interface)
        self.monitor = MeasuredSpeedMonitor(self.envelope, config.interlock.debounce_samples)
        interlock = config.interlock
        self.confirmations = Confirmations(interlock)
        self.expectation = SpeedExpectation(
            self.planner,
            interlock.measurement_tolerance_rpm,
            interlock.command_confirm_s + self.planner.settle_s,
            interlock.debounce_samples,
        )
        self.furnace_expectation = FurnaceExpectation(interlock.command_confirm_s, interlock.debounce_samples)
        self.run_orders = RunOrders(interlock.command_confirm_s)
        self._node_state: NodeState | None = None
        """The node's state in the last NodeStatus (None before the first, or after losing the node)."""
        self._estop_pending = False
        self._estop_sent_s = 0.0
        self.estops_sent = 0
        self._counters = self.drives.counters if isinstance(self.drives, MillbusDrives) else {}
        """The millbus wire's alive counters, per kind (empty on other backends)."""
        self.commanded = STANDSTILL
        self.trajectory: Trajectory | None = None
        self._trajectory_start_s = 0.0
        self._limits_hold = False
        """The trajectory waits at its start until the drives report its limits in force (SAFETY 28)."""
        self._arm_source: str | None = None
        """Who asked to arm, while the ARM waits for the drives' limits (None: no ARM waiting)."""
        self.furnace_target_c: float | None = None
        self.furnace_setpoint_c = config.furnace.ambient_temp_c
        self.heating_rate_c_per_min = config.furnace.max_heating_rate_c_per_min
        self.trip_cause = ""
        self._reset_pending = False
        self._reset_source = "operator"
        self._reset_sent: CommandCode | None = None
        self._reset_until_s = 0.0
        self._disarm_pending = False
        self._last_tick_s = clock.now()
        self._next_heartbeat_s = clock.now()
        self._next_setpoints_s = clock.now()

    # ------------------------------------------------------------------ state
    @property
    def state(self) -> ControllerState:
        """The controller's state."""
        return self.machine.state

    @property
    def node_status(self) -> NodeStatus | None:
        """The freshest NodeStatus, or None before the first."""
        last = self.tracker.tracks[NodeStatus].last
        return last if isinstance(last, NodeStatus) else None

    @property
    def measured(self) -> DriveTelemetry | None:
        """The freshest measured drive speeds, or None before the first."""
        last = self.tracker.tracks[DriveTelemetry].last
        return last if isinstance(last, DriveTelemetry) else None

    @property
    def furnace(self) -> FurnaceTelemetry | None:
        """The freshest furnace telemetry, or None before the first."""
        last = self.tracker.tracks[FurnaceTelemetry].last
        return last if isinstance(last, FurnaceTelemetry) else None

    def status(self) -> Status:
        """A snapshot of everything an operator needs to see."""
        return build_status(self)

    def _emit(self, kind: EventKind, source: str, message: str, **data: object) -> None:
        event = Event(self.clock.now(), kind, source, message, dict(data))
        log.info("%s [%s] %s", kind, source, message)
        if self.listener is not None:
            self.listener(event)

    def _on_transition(self, transition: Transition) -> None:
        self._emit(
            EventKind.STATE,
            "controller",
            f"{transition.source} → {transition.target}: {transition.reason}",
            source_state=str(transition.source),
            target_state=str(transition.target),
            reason=transition.reason,
        )

    # ------------------------------------------------------------------ wire
    def _command(self, code: CommandCode, source: str, reason: str) -> None:
        """Send a command and await the node's confirmation of it (docs/safety.md#every-command-confirmed)."""
        self.drives.command(code)
        self.confirmations.sent(code, source, reason, self.clock.now())
        self._emit(EventKind.COMMAND, source, f"{code.name}: {reason}", command=code.name)

    def _send_estop(self) -> None:
        self.drives.estop(EStopSource.CONTROLLER)
        self._estop_pending = True
        self._estop_sent_s = self.clock.now()
        self.estops_sent += 1

    # ------------------------------------------------------------------ operator commands
    def _require(self, operation: Operation, what: str, source: str) -> None:
        allowed = CONTROLLER_ALLOWS[operation]
        if self.state not in allowed:
            reason = f"{what} is not possible in state {self.state} (possible in {', '.join(sorted(allowed))})"
            if self.state is S.TRIPPED:
                reason += f"; tripped by: {self.trip_cause} — reset first"
            self._emit(EventKind.REFUSAL, source, reason)
            raise CommandRefused(reason)

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

    def _refuse(self, source: str, reason: str) -> None:
        self._emit(EventKind.REFUSAL, source, reason)
        raise CommandRefused(reason)

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

    def set_furnace(
        self, temp_c: float | None, *, rate_c_per_min: float | None = None, source: str = "operator"
    ) -> None:
        """Set the furnace target (ramped at the heating rate); None turns the heater off."""
        if temp_c is not None:  # turning the heater off is allowed in every state
            self._require(Operation.FURNACE, "set the furnace", source)
        furnace = self._furnace_part(temp_c, rate_c_per_min, source)  # a rate with the heater off: refused
        if furnace is None:
            self.furnace_target_c = None
            self._emit(EventKind.COMMAND, source, "heater off")
            return
        self._apply_furnace(*furnace, source)

    def _furnace_part(
        self, temp_c: float | None, rate_c_per_min: float | None, source: str
    ) -> tuple[float, float] | None:
        """The furnace part of a command, checked: (target °C, heating rate °C/min), None when it has none.

        A heating rate with no target is refused, not ignored (docs/safety.md#setpoint-interlock).
        """
        if temp_c is None:
            if rate_c_per_min is not None:
                reason = (
                    f"heating rate {rate_c_per_min} °C/min given without a furnace target: there is nothing to "
                    "heat to, and the rate would be ignored; give the target with it, or leave the rate out"
                )
                self._emit(EventKind.REFUSAL, source, reason, heating_rate_c_per_min=rate_c_per_min)
                raise InvalidInputError(reason)
            return None
        return temp_c, self._check_furnace(temp_c, rate_c_per_min, source)

    def _check_furnace(self, temp_c: float, rate_c_per_min: float | None, source: str) -> float:
        """Check a furnace target and heating rate (°C, °C/min); return the rate in force, or refuse."""
        rate = self.config.furnace.max_heating_rate_c_per_min if rate_c_per_min is None else rate_c_per_min
        for verdict in (self.envelope.check(0.0, 0.0, temp_c), self.envelope.check_heating_rate(rate)):
            if not verdict.ok:
                self._emit(EventKind.REFUSAL, source, verdict.reason(), temp_c=temp_c)
                raise InterlockRefused(verdict, "furnace setpoint")
        return rate

    def _apply_furnace(self, temp_c: float, rate_c_per_min: float, source: str) -> None:
        if self.furnace_target_c is None:  # ramp from where the furnace is
            furnace = self.furnace
            self.furnace_setpoint_c = furnace.temp_c if furnace is not None else self.config.furnace.ambient_temp_c
        self.furnace_target_c = temp_c
        self.heating_rate_c_per_min = rate_c_per_min
        self._emit(
            EventKind.COMMAND, source, f"furnace to {temp_c:.1f} °C at {rate_c_per_min:.1f} °C/min", temp_c=temp_c
        )

    def stop(self, source: str = "operator", reason: str = "operator request") -> None:
        """Controlled stop (category 1): the node ramps both drives down inside the envelope, heater off."""
        self._require(Operation.STOP, "stop", source)
        self._begin_stop(source, reason)

    def _begin_stop(self, source: str, reason: str) -> None:
        self.trajectory = None
        self.furnace_target_c = None
        self._command(CommandCode.STOP, source, reason)
        self.run_orders.stop_sent(self.clock.now())
        self._expect_stop()
        if self.machine.can_go(S.STOPPING):
            self.machine.go(S.STOPPING, f"{source}: {reason}")
        self.commanded = STANDSTILL

    def _expect_stop(self) -> None:
        """From now on the drives must stay under the stop's ceiling and reach standstill by its end."""
        measured = self.measured
        self.expectation.begin_stop(
            self.clock.now(), None if measured is None else (measured.rotary_rpm, measured.vibration_rpm)
        )

    def estop(self, source: str = "operator") -> None:
        """Emergency stop: the E-stop frame at the highest priority, repeated until the node reports it; a trip."""
        self.drives.estop(EStopSource.OPERATOR if source != "controller" else EStopSource.CONTROLLER)
        self._estop_pending = True
        self._estop_sent_s = self.clock.now()
        self._emit(EventKind.COMMAND, source, "E-STOP")
        self._trip(f"E-stop by {source}", source)

    def _escalate(self, cause: str) -> None:
        """A stop that does not happen: E-stop (repeated until the node reports it), and a trip naming why."""
        self._send_estop()
        self._emit(EventKind.TRIP, "controller", f"E-stop: {cause}")
        self._trip(f"{cause}: E-stop sent", "controller")

    def _uncommanded(self, cause: str) -> None:
        """The node does what nobody commanded: a trip, or an E-stop where a stop was already commanded."""
        if self.state in (S.STOPPING, S.TRIPPED):
            self._escalate(cause)
        else:
            self._trip(cause, "controller")

    def reset(self, source: str = "operator") -> None:
        """Clear a latched trip: only with fresh telemetry and both drives at standstill."""
        self._require(Operation.RESET, "reset", source)
        now = self.clock.now()
        stale = self.tracker.stale(now)
        if stale:
            self._refuse(source, f"reset refused: {'; '.join(stale)}")
        measured = self.measured
        if measured is None or max(abs(measured.rotary_rpm), abs(measured.vibration_rpm)) > STANDSTILL_RPM:
            shown = "unknown" if measured is None else f"{measured.rotary_rpm:.1f}/{measured.vibration_rpm:.1f} rpm"
            self._refuse(source, f"reset refused: drives not at standstill (measured {shown})")
        self.tracker.reset_links()
        self.monitor.reset()
        self._reset_pending = True
        self._reset_source = source
        self._reset_sent = None
        self._reset_until_s = now + RESET_TIMEOUT_S
        self._emit(EventKind.COMMAND, source, "reset requested")
        self._advance_reset(self.node_status)

    def _advance_reset(self, node: NodeStatus | None) -> None:
        """Send what the node's state needs for a pending reset: RESET in FAULT, DISARM in ARMED (once each)."""
        if node is None:
            return
        wanted = {NodeState.FAULT: CommandCode.RESET, NodeState.ARMED: CommandCode.DISARM}.get(node.state)
        if wanted is not None and wanted is not self._reset_sent:
            self._reset_sent = wanted
            reason = f"clear latched trip: {self.trip_cause}" if wanted is CommandCode.RESET else "reset: to DISABLED"
            self._command(wanted, self._reset_source, reason)

    # ------------------------------------------------------------------ trips
    def _trip(self, cause: str, source: str = "interlock") -> None:
        if self.state is S.TRIPPED:
            return
        self.trip_cause = cause
        self._reset_pending = False
        self._emit(EventKind.TRIP, source, cause)
        self.trajectory = None
        self.furnace_target_c = None
        self._command(CommandCode.STOP, "interlock", f"trip: {cause}")
        self.run_orders.stop_sent(self.clock.now())
        self._expect_stop()
        self.commanded = STANDSTILL
        self.machine.go(S.TRIPPED, cause)

    # ------------------------------------------------------------------ the control loop
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

    @property
    def invalid_frames(self) -> int:
        """Frames read that do not fit the DBC (counted by the bus reader)."""
        return self.reader.counts.malformed

    @property
    def foreign_estops(self) -> int:
        """E-stop frames read from other senders (the node acts on them)."""
        return self.reader.counts.estops

    @property
    def moving_commanded(self) -> bool:
        """True while the controller commands a speed other than standstill (or a ramp is under way)."""
        return self.state in (S.ARMED, S.RUNNING) and (self.commanded != STANDSTILL or self.trajectory is not None)

    def _judge_node_change(self, node: NodeState) -> None:
        """Any node state change the controller did not command trips (E-stop where a stop was commanded).

        The one change judged against what the controller sent before rather
        than what it commands now: a RUNNING that answers its own order to run,
        which a STOP overtook (docs/safety.md#a-stop-overtaking-a-setpoint).
        """
        before, self._node_state = self._node_state, node
        now = self.clock.now()
        overtaken = node is NodeState.RUNNING and self.run_orders.explains_running(now)
        self.run_orders.reported(node)
        if before is None:  # first status (or first after losing the node): only a running node is suspect
            if node is NodeState.RUNNING and not self.moving_commanded and self.state is not S.DISCONNECTED:
                if overtaken:
                    self._stop_overtook_setpoint(now)
                    return
                self._uncommanded(f"node reports RUNNING, which the controller (state {self.state}) did not command")
            return
        if node_change_commanded(before, node, self.confirmations.in_flight(now), self.moving_commanded):
            return
        if overtaken:  # before is ARMED: any other report ends the order
            self._stop_overtook_setpoint(now)
            return
        restarted = ": the node restarted, or another sender commands it" if node is NodeState.DISABLED else (
            ": another sender commands the node"
        )
        self._uncommanded(
            f"node went {before.name} → {node.name}, which the controller (state {self.state}) did not command"
            + restarted
        )

    def _stop_overtook_setpoint(self, now: float) -> None:
        """The node ran on the controller's own setpoint, sent just before a STOP it has not taken yet: the stop holds.

        The STOP stays pending with its first deadline (pending again if a
        status from before the node took it had confirmed it), so RUNNING must
        end within the STOP's bound or the controller sends an E-stop; a
        controller that took that earlier status for the stop's end is
        STOPPING again, under the stop's ceiling.
        """
        stop_s = self.run_orders.stop_s
        self.confirmations.reopen(CommandCode.STOP, "controller", "the node ran on a setpoint sent before the STOP",
                                  stop_s)
        self._emit(
            EventKind.COMMAND,
            "controller",
            f"node RUNNING {now - stop_s:.2f} s after the STOP, on the setpoint sent before it (the node takes "
            "frames in order and has not taken the STOP yet): the stop holds, STOP pending "
            "(docs/safety.md#a-stop-overtaking-a-setpoint)",
        )
        if self.state is S.ARMED:
            self._expect_stop()
            self.machine.go(S.STOPPING, "node RUNNING on a setpoint sent before the STOP: the stop is not complete")

    def _on_node_status(self, status: NodeStatus) -> None:
        now = self.clock.now()
        self._judge_node_change(status.state)
        for confirmed in self.confirmations.confirm(status, now):
            log.debug("%s confirmed by node %s after %d send(s)", confirmed.code.name, status.state.name,
                      confirmed.sends)
        if self._estop_pending and FaultFlag.ESTOP in status.fault_bits:
            self._estop_pending = False
        state, node = self.state, status.state
        if state is S.TRIPPED and self._reset_pending:
            if node is NodeState.DISABLED and not status.fault_bits:
                self._reset_pending = False
                self._disarm_pending = False  # a DISARM lost before the trip is over: this one was the reset's
                self.trip_cause = ""
                self.expectation.end_stop()
                self.machine.go(S.DISABLED, "reset complete: node DISABLED, causes cleared")
            else:
                self._advance_reset(status)
            return
        if node is NodeState.FAULT:
            if state is S.TRIPPED:
                return
            cause = FaultCode(status.first_fault).name
            detail = self.drives.fault_detail()
            self._trip(f"node fault {cause} (fault bits {status.fault_bits!r})" + (f": {detail}" if detail else ""),
                       "node")
            return
        if state is S.DISCONNECTED:
            if node is NodeState.DISABLED:
                self.machine.go(S.DISABLED, "node seen, DISABLED")
            else:
                self._trip(f"node found in state {node.name} at connect: expected DISABLED", "node")
        elif state is S.DISABLED and node is NodeState.ARMED:
            self.machine.go(S.ARMED, "node ARMED")
        elif state is S.ARMED and node is NodeState.RUNNING:
            self.machine.go(S.RUNNING, "node RUNNING")
        elif state is S.STOPPING and node is NodeState.ARMED:
            self.expectation.end_stop()
            self.machine.go(S.ARMED, "controlled stop complete")
        elif state in (S.ARMED, S.STOPPING) and node is NodeState.DISABLED and self._disarm_pending:
            self._disarm_pending = False  # DISARM, then maybe a STOP it overtook (a no-op at rest): both confirmed
            self.expectation.end_stop()
            self.machine.go(S.DISABLED, "node DISABLED (disarmed)" if state is S.ARMED else
                            "node DISABLED: it took the DISARM sent before the STOP (at rest, disabled)")
        elif state in (S.ARMED, S.RUNNING, S.STOPPING) and node is NodeState.DISABLED:
            self._trip(f"node reports DISABLED while the controller is {state} with no DISARM of its own pending: "
                       "the node restarted, or another sender disarmed it", "node")

    def _on_measured(self, measured: DriveTelemetry) -> None:
        """Check a measured pair: the envelope (until tripped), and what was commanded (in every state)."""
        if self.state is S.DISCONNECTED:
            return
        if self.state is not S.TRIPPED:
            reason = self.monitor.update(measured.rotary_rpm, measured.vibration_rpm)
            if reason is not None:
                self._trip(reason)
        reason = self.expectation.check(self.clock.now(), measured.rotary_rpm, measured.vibration_rpm)
        if reason is not None:
            self.expectation.reset()
            self._uncommanded(reason)

    def _on_furnace(self, report: FurnaceTelemetry) -> None:
        """Check the node's heater against the furnace targets commanded (in every state but DISCONNECTED)."""
        if self.state is S.DISCONNECTED:
            return
        reason = self.furnace_expectation.check(self.clock.now(), report)
        if reason is not None:
            self.furnace_expectation.reset()
            self._uncommanded(reason)

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

    def _furnace_command(self) -> float | None:
        """The furnace setpoint the Setpoints frames carry now (°C, on the wire's grid); None: heater off."""
        if self.state in (S.ARMED, S.RUNNING) and self.furnace_target_c is not None:
            return round(self.furnace_setpoint_c, 1)
        return None

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


__all__ = ["STANDSTILL_RPM", "CommandRefused", "Controller"]
