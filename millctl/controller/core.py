"""The controller's core: its state, what it records, and what every part of it sends and trips with.

:class:`ControllerCore` holds everything :class:`~millctl.controller.Controller`
knows (built in one ``__init__``) and the few acts every other part uses:
emitting an event, sending a command or an E-stop, refusing, tripping. The
parts that judge the node's reports (:mod:`.node_reports`) and command the
furnace (:mod:`.furnace_commands`) build on it; :mod:`.controller` is the
operator's commands and the control loop. A split by concern of one class,
so every attribute stays where the rest of millctl reads it.
"""

from __future__ import annotations

import logging

import can

from millctl.clock import Clock
from millctl.config.models import MillConfig
from millctl.controller.confirm import Confirmations
from millctl.controller.events import Event, EventKind, EventListener
from millctl.controller.expect import SpeedExpectation
from millctl.controller.furnace_expect import FurnaceExpectation
from millctl.controller.monitor import MeasuredSpeedMonitor
from millctl.controller.overtake import RunOrders
from millctl.controller.states import ControllerState, StateMachine, Transition
from millctl.controller.tracking import TelemetryTracker
from millctl.drives.base import DrivesBackend
from millctl.drives.millbus import MillbusDrives
from millctl.drives.registry import open_drives
from millctl.errors import InterlockError
from millctl.protocol import (
    Codec,
    CommandCode,
    DriveTelemetry,
    EStopSource,
    FurnaceTelemetry,
    NodeState,
    NodeStatus,
    default_codec,
)
from millctl.protocol.bus_health import BusHealthMonitor
from millctl.safety import STANDSTILL, Envelope, RampPlanner, Trajectory
from millctl.safety.commands import CONTROLLER_ALLOWS, Operation

log = logging.getLogger(__name__)

S = ControllerState

STANDSTILL_RPM = 1.0
"""Measured speeds below this count as standstill (rpm)."""

RESET_TIMEOUT_S = 2.0
"""A reset the node has not completed within this time is given up, with its reason (s)."""


class CommandRefused(InterlockError):
    """A command that the current state does not allow; nothing was sent."""


class ControllerCore:
    """The mill's controller on one bus: its state and its shared acts (:class:`~millctl.controller.Controller`)."""

    def __init__(
        self,
        config: MillConfig,
        bus: can.BusABC,
        clock: Clock,
        *,
        codec: Codec | None = None,
        listener: EventListener | None = None,
        drives: DrivesBackend | None = None,
        furnace_bus: can.BusABC | None = None,
    ) -> None:
        """Bind the controller to ``bus`` and ``clock``; open the configured drives unless ``drives`` is given.

        ``furnace_bus``: the furnace node's channel beside CiA 402 drives, opened (and shut) by the caller; None:
        the backend opens ``[drives.furnace_bus]`` itself when configured (``drives.registry.open_drives``).
        """
        self.config = config
        self.bus = bus
        self.clock = clock
        self.codec = codec or default_codec()
        self.listener = listener
        self.envelope = Envelope.from_config(config)
        self.drives: DrivesBackend = (
            drives if drives is not None else open_drives(config, bus, self.codec, self.envelope,
                                                          furnace_bus=furnace_bus)
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

    def _require(self, operation: Operation, what: str, source: str) -> None:
        allowed = CONTROLLER_ALLOWS[operation]
        if self.state not in allowed:
            reason = f"{what} is not possible in state {self.state} (possible in {', '.join(sorted(allowed))})"
            if self.state is S.TRIPPED:
                reason += f"; tripped by: {self.trip_cause} — reset first"
            self._emit(EventKind.REFUSAL, source, reason)
            raise CommandRefused(reason)

    def _refuse(self, source: str, reason: str) -> None:
        self._emit(EventKind.REFUSAL, source, reason)
        raise CommandRefused(reason)

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


__all__ = ["RESET_TIMEOUT_S", "STANDSTILL_RPM", "CommandRefused", "ControllerCore"]
