"""The simulated node: its state machine, frame handling and the tick that runs everything.

``Node.tick()`` drains the bus, acts on an E-stop first, advances the drives
and the furnace by the time since the last tick, runs every safety check,
and sends the periodic frames that are due. It reads time only from the
injected clock, so tests step it without sleeping (docs/operations.md,
"Simulated node"; SAFETY.md items 1–4, 6, 8–12).
"""

from __future__ import annotations

import logging
import time

import can
import numpy as np

from firmware_sim.drives import DrivePair
from firmware_sim.faults import FaultInjector
from firmware_sim.furnace import FurnaceModel
from firmware_sim.link import GUARDED, LinkMonitor
from firmware_sim.monitor import SpeedMonitor
from firmware_sim.motion import Motion
from firmware_sim.telemetry import PhysicsCache, PhysicsWorker, Schedule
from millctl.clock import Clock
from millctl.config.models import MillConfig
from millctl.errors import InterlockError
from millctl.protocol import (
    NO_FAULTS,
    AliveCounter,
    BusReader,
    Codec,
    Command,
    CommandCode,
    Decoded,
    DriveTelemetry,
    FaultCode,
    FaultFlag,
    FurnaceTelemetry,
    MillMessage,
    NodeState,
    NodeStatus,
    PhysicsTelemetry,
    ProtocolError,
    RefusalCode,
    Setpoints,
    SimFault,
    SimFaultCode,
    default_codec,
)
from millctl.safety import Envelope
from millctl.safety.commands import NODE_ACCEPTS, NODE_SETPOINTS_IN, NODE_TRANSITIONS

log = logging.getLogger(__name__)

MOVING = (NodeState.ARMED, NodeState.RUNNING, NodeState.STOPPING)
"""States in which the heartbeat watchdog is armed."""


class IllegalNodeTransition(InterlockError):
    """A state change that :data:`millctl.safety.commands.NODE_TRANSITIONS` does not allow (a bug)."""


class Node:
    """The simulated drive-and-furnace node on one CAN bus (times in s, speeds in rpm)."""

    UNSENT: tuple[type[MillMessage], ...] = ()
    """Periodic frames this node does not send (the furnace-only node: no drives, no physics)."""

    def __init__(
        self,
        config: MillConfig,
        bus: can.BusABC,
        clock: Clock,
        *,
        fault_injection: bool = False,
        seed: int = 0,
        codec: Codec | None = None,
        physics_worker: PhysicsWorker = "inline",
        estop_bus: can.BusABC | None = None,
    ) -> None:
        self.config = config
        self.bus = bus
        self.clock = clock
        self.codec = codec if codec is not None else default_codec()
        self.envelope = Envelope.from_config(config)
        self.drives = DrivePair(config, np.random.default_rng(seed))
        self.furnace = FurnaceModel(config.furnace, config.timing.node_tick_s)
        self.faults = FaultInjector(config, self.drives, self.furnace, enabled=fault_injection, seed=seed)
        self.reader = BusReader(bus, "node", estop_bus=estop_bus)  # estop_bus: E-stops only (SocketCAN)
        self.link = LinkMonitor(config)
        self.monitor = SpeedMonitor(config, self.envelope)
        self.motion = Motion(config, self.envelope)
        self.schedule = Schedule(self.codec)
        self.physics = PhysicsCache(config, worker=physics_worker)
        self._counters: dict[type[MillMessage], AliveCounter] = {
            kind: AliveCounter() for kind in (NodeStatus, DriveTelemetry, FurnaceTelemetry)
        }
        self._state = NodeState.DISABLED
        self._fault_bits = NO_FAULTS
        self._first_fault = FaultCode.NONE
        self._refused = 0
        self._last_refusal = RefusalCode.NONE
        self._last_setpoint: Setpoints | None = None
        self._refreshed_s = 0.0
        self._last_tick_s: float | None = None
        self._measured = (0.0, 0.0)
        self.frames_sent = 0
        self.setpoints_expired = 0
        """Controlled stops because the drive setpoints were not refreshed (SAFETY 26)."""
        self.tx_errors = 0
        self.tick_count = 0
        self._tick_total_s = 0.0
        self._tick_max_s = 0.0
        log.info(
            "node DISABLED (envelope %s, fault injection %s)",
            self.envelope.description,
            "on" if fault_injection else "off",
        )

    def close(self) -> None:
        """Release the physics worker (the bus belongs to the caller)."""
        self.physics.close()

    # -- read-only views for tests and benchmarks ------------------------------------------------

    @property
    def state(self) -> NodeState:
        """The node's state."""
        return self._state

    @property
    def fault_bits(self) -> FaultFlag:
        """Latched faults."""
        return self._fault_bits

    @property
    def first_fault(self) -> FaultCode:
        """The first cause of the latched faults (NONE when none)."""
        return self._first_fault

    @property
    def measured_speeds_rpm(self) -> tuple[float, float]:
        """The last measured (ω_r, ω_v) (rpm), as DriveTelemetry reports them."""
        return self._measured

    @property
    def true_speeds_rpm(self) -> tuple[float, float]:
        """The simulated rotors' true (ω_r, ω_v) (rpm)."""
        return self.drives.rotary.speed_rpm, self.drives.vibration.speed_rpm

    @property
    def furnace_temp_c(self) -> float:
        """Furnace temperature (°C)."""
        return self.furnace.temp_c

    @property
    def heater_on(self) -> bool:
        """True while the heater loop is on."""
        return self.furnace.heater_on

    @property
    def last_setpoint(self) -> Setpoints | None:
        """The last accepted Setpoints frame (None before the first)."""
        return self._last_setpoint

    @property
    def refused_setpoints(self) -> int:
        """Refused frames (setpoints and commands) since boot (not wrapped)."""
        return self._refused

    @property
    def last_refusal(self) -> RefusalCode:
        """Why the last refused frame was refused."""
        return self._last_refusal

    @property
    def tick_mean_s(self) -> float:
        """Mean duration of ``tick()`` (s, time.perf_counter)."""
        return self._tick_total_s / self.tick_count if self.tick_count else 0.0

    @property
    def tick_max_s(self) -> float:
        """Longest ``tick()`` (s, time.perf_counter)."""
        return self._tick_max_s

    # -- the tick -------------------------------------------------------------------------------------

    def tick(self) -> None:
        """One node cycle: every waiting frame (an E-stop acted on first), physics, safety checks, periodic frames."""
        started = time.perf_counter()
        now = self.clock.now()
        dt = 0.0 if self._last_tick_s is None else max(now - self._last_tick_s, 0.0)
        self._last_tick_s = now
        batch = self.reader.drain()
        if batch.estop:
            self._latch(FaultFlag.ESTOP, "E-stop frame received", now)
        command = self.motion.command(now)
        self.drives.step(command.omega_r_rpm, command.omega_v_rpm, dt)
        self.furnace.step(dt)
        for frame in batch.frames:
            self._handle(frame, now)
        self._checks(now, dt)
        self._transmit(now, dt)
        elapsed = time.perf_counter() - started
        self.tick_count += 1
        self._tick_total_s += elapsed
        self._tick_max_s = max(self._tick_max_s, elapsed)

    def _handle(self, frame: can.Message, now: float) -> None:
        try:
            decoded = self.codec.decode(frame)
        except ProtocolError as exc:
            self.reader.malformed(frame, exc)
            return
        if decoded.kind is SimFault:
            if isinstance(decoded.message, SimFault):
                self.faults.handle(decoded.message)
            return
        if decoded.kind not in GUARDED:
            return
        status = self.link.check(decoded, now)
        if decoded.kind is Command:
            self._command(decoded, status.fresh, now)
        elif decoded.kind is Setpoints:
            self._setpoints(decoded, status.fresh, now)

    # -- commands and setpoints -----------------------------------------------------------------------

    def _refuse(self, code: RefusalCode, what: str) -> None:
        self._refused += 1
        self._last_refusal = code
        log.info("refused %s: %s (state %s)", what, code.name, self._state.name)

    def _command(self, decoded: Decoded, fresh: bool, now: float) -> None:
        message = decoded.message
        if not isinstance(message, Command):
            self._refuse(RefusalCode.E2E, "command with a bad CRC")
            return
        if not fresh:
            self._refuse(RefusalCode.NOT_FRESH, f"{message.command.name} (stale counter)")
            return
        handler = {
            CommandCode.ARM: self._arm,
            CommandCode.DISARM: self._disarm,
            CommandCode.STOP: self._stop,
            CommandCode.RESET: self._reset,
        }[message.command]
        code = handler(now)
        if code is not RefusalCode.NONE:
            self._refuse(code, message.command.name)

    def _arm(self, now: float) -> RefusalCode:
        if self._state is NodeState.FAULT or self._fault_bits:
            return RefusalCode.FAULT_LATCHED
        if self._state not in NODE_ACCEPTS[CommandCode.ARM]:
            return RefusalCode.WRONG_STATE
        if not self.link.heartbeat_live(now):
            return RefusalCode.NOT_FRESH
        self.motion.reset(now)
        self._set_state(NodeState.ARMED, "ARM with a live heartbeat")
        return RefusalCode.NONE

    def _disarm(self, now: float) -> RefusalCode:
        if self._state is NodeState.FAULT:
            return RefusalCode.FAULT_LATCHED
        if self._state not in NODE_ACCEPTS[CommandCode.DISARM]:
            return RefusalCode.WRONG_STATE
        if not self._standstill():
            return RefusalCode.NOT_STANDSTILL
        self.furnace.heater_off()
        self.motion.reset(now)
        self._set_state(NodeState.DISABLED, "DISARM")
        return RefusalCode.NONE

    def _stop(self, now: float) -> RefusalCode:
        if self._state in (NodeState.ARMED, NodeState.RUNNING):
            self.begin_stop(now, "STOP command")
        return RefusalCode.NONE

    def _reset(self, now: float) -> RefusalCode:
        if self._state not in NODE_ACCEPTS[CommandCode.RESET]:
            return RefusalCode.WRONG_STATE
        if not self._standstill():
            return RefusalCode.NOT_STANDSTILL
        present = self._present_causes(now)
        if present:
            log.info("RESET refused: causes still present: %s", present)
            return RefusalCode.FAULT_LATCHED
        self._fault_bits = NO_FAULTS
        self._first_fault = FaultCode.NONE
        self.link.reset_scores()
        self.motion.reset(now)
        self.monitor = SpeedMonitor(self.config, self.envelope)
        self._set_state(NodeState.DISABLED, "RESET at standstill with the causes cleared")
        return RefusalCode.NONE

    def _present_causes(self, now: float) -> FaultFlag:
        """Latched faults whose cause is still there (RESET needs none)."""
        bits, present = self._fault_bits, NO_FAULTS
        if FaultFlag.WATCHDOG in bits and not self.link.heartbeat_live(now):
            present |= FaultFlag.WATCHDOG
        if FaultFlag.E2E_LINK in bits and self.link.errors_present(now):
            present |= FaultFlag.E2E_LINK
        if FaultFlag.OVERTEMP in bits and self.furnace.temp_c >= self.config.furnace.over_temp_c:
            present |= FaultFlag.OVERTEMP
        injected = {
            FaultFlag.STALL: (SimFaultCode.VIB_STALL,),
            FaultFlag.OVERSPEED: (SimFaultCode.ROTARY_RUNAWAY,),
            FaultFlag.ENVELOPE: (SimFaultCode.ROTARY_RUNAWAY,),
            FaultFlag.SENSOR: (SimFaultCode.SENSOR_STUCK, SimFaultCode.SENSOR_NOISY),
            FaultFlag.HEATER_VERIFY: (SimFaultCode.HEATER_FAIL,),
            FaultFlag.OVERTEMP: (SimFaultCode.HEATER_FAIL,),
        }
        for flag, codes in injected.items():
            if flag in bits and any(self.faults.is_active(code) for code in codes):
                present |= flag
        return present

    def _setpoints(self, decoded: Decoded, fresh: bool, now: float) -> None:
        message = decoded.message
        if not isinstance(message, Setpoints) or not fresh:
            self._refuse(RefusalCode.E2E, "setpoints with a bad CRC or stale counter")
            return
        refusal = RefusalCode.NONE
        if self._state not in NODE_SETPOINTS_IN:
            refusal = {NodeState.DISABLED: RefusalCode.NOT_ARMED, NodeState.FAULT: RefusalCode.FAULT_LATCHED}.get(
                self._state, RefusalCode.WRONG_STATE
            )
        else:
            refusal = self.motion.check(message, now)
        if refusal is not RefusalCode.NONE:
            self._refuse(refusal, f"setpoints {message}")
            return
        self.motion.accept(message, now)
        self.furnace.command(message.heater_on, message.furnace_c)
        self._refreshed_s = now
        self._last_setpoint = message
        if (message.rotary_rpm > 0.0 or message.vibration_rpm > 0.0) and self._state is NodeState.ARMED:
            self._set_state(NodeState.RUNNING, "nonzero setpoint")

    # -- state and faults -----------------------------------------------------------------------------

    def _set_state(self, state: NodeState, reason: str) -> None:
        """Move along :data:`~millctl.safety.commands.NODE_TRANSITIONS` only (anything else is a bug)."""
        if state is not self._state:
            if state not in NODE_TRANSITIONS[self._state]:
                raise IllegalNodeTransition(
                    f"node cannot go {self._state.name} → {state.name} ({reason}); allowed: "
                    f"{', '.join(sorted(s.name for s in NODE_TRANSITIONS[self._state]))}"
                )
            log.info("node %s → %s: %s", self._state.name, state.name, reason)
            self._state = state

    def begin_stop(self, now: float, reason: str) -> None:
        """Begin a controlled stop with the heater off (STOPPING, or kept in FAULT)."""
        self.motion.begin_stop(now)
        self.furnace.heater_off()
        if self._state in (NodeState.ARMED, NodeState.RUNNING):
            self._set_state(NodeState.STOPPING, reason)

    def shutdown_stop(self) -> None:
        """The process is ending: begin a controlled stop from any state, heater off."""
        now = self.clock.now()
        if self._state in (NodeState.ARMED, NodeState.RUNNING):
            self.begin_stop(now, "shutdown")
        elif not self.motion.zero:
            self.motion.begin_stop(now)
        self.furnace.heater_off()

    @property
    def at_standstill(self) -> bool:
        """Both drives at rest and no stop under way."""
        return self._standstill()

    def _latch(self, flag: FaultFlag, reason: str, now: float) -> None:
        new = flag & ~self._fault_bits
        if not new:
            return
        if self._first_fault is FaultCode.NONE:
            self._first_fault = FaultCode.of(_lowest(new))
        self._fault_bits |= new
        log.warning("fault %s latched: %s", new, reason)
        self.motion.begin_stop(now)
        self.furnace.heater_off()
        self._set_state(NodeState.FAULT, reason)

    def _at_rest(self) -> bool:
        """Both drives at rest: measured and reference speeds within the measurement tolerance."""
        tol = self.config.interlock.measurement_tolerance_rpm
        drives = self.drives
        return max(*self._measured, drives.rotary_ref.speed_rpm, drives.vibration_ref.speed_rpm) <= tol

    def _standstill(self) -> bool:
        """At rest with standstill commanded and no stop under way."""
        return self.motion.zero and self._at_rest()

    def _link_and_furnace_faults(self, now: float) -> FaultFlag:
        """The furnace's checks, the watchdog, the E2E link and the heater's setpoint refresh (every node mode)."""
        faults = self.furnace.check()
        if self._state in MOVING and not self.link.heartbeat_live(now):
            faults |= FaultFlag.WATCHDOG
        if self.link.faulted:
            faults |= FaultFlag.E2E_LINK
        if self.furnace.heater_on and now - self._refreshed_s > self.config.furnace.setpoint_refresh_s:
            faults |= FaultFlag.HEATER_TIMEOUT
        return faults

    def _checks(self, now: float, dt: float) -> None:
        measured = self.drives.sample()
        self._measured = measured
        reference = (self.drives.rotary_ref.speed_rpm, self.drives.vibration_ref.speed_rpm)
        faults = self.monitor.check(measured, reference, dt) | self._link_and_furnace_faults(now)
        if faults:
            self._latch(faults, f"checks: {faults!r}", now)
        self._expire_setpoints(now)
        if self.motion.stop is not None and self.motion.stop_done(now) and self._at_rest():
            self.motion.reset(now)
            if self._state is NodeState.STOPPING:
                self._set_state(NodeState.ARMED, "controlled stop complete")
        if self._state is NodeState.RUNNING and self.motion.zero and self._standstill():
            self._set_state(NodeState.ARMED, "zero setpoints at standstill")

    def _expire_setpoints(self, now: float) -> None:
        """A running node whose drive setpoints were not refreshed within the expiry stops (SAFETY 26).

        A heartbeat alone does not keep the drives turning: a forger that keeps
        the watchdog fed (replayed or echoed heartbeats) while the controller is
        gone gets a controlled stop within ``timing.setpoint_expiry_s``.
        """
        expiry_s = self.config.timing.setpoint_expiry_s
        if self._state is NodeState.RUNNING and now - self._refreshed_s > expiry_s:
            reason = (
                f"drive setpoints expired: none accepted for {now - self._refreshed_s:.2f} s, bound {expiry_s:.2f} s "
                "(timing.setpoint_expiry_periods, min_setpoint_expiry_s; docs/safety.md#setpoint-expiry)"
            )
            log.warning("%s: controlled stop", reason)
            self.setpoints_expired += 1
            self.begin_stop(now, reason)

    # -- transmit -------------------------------------------------------------------------------------

    def _frame(self, kind: type[MillMessage]) -> MillMessage:
        if kind is NodeStatus:
            return NodeStatus(
                self._state,
                self._fault_bits,
                self._first_fault,
                self._refused % 256,
                self._last_refusal,
                self.link.issue_challenge(self.clock.now()),
            )
        if kind is DriveTelemetry:
            torque_r, torque_v = self.drives.torques_nm()
            return self.codec.saturated(DriveTelemetry(*self._measured, torque_r, torque_v))
        if kind is FurnaceTelemetry:
            furnace = self.furnace
            return self.codec.saturated(
                FurnaceTelemetry(furnace.temp_c, furnace.setpoint_c, furnace.duty * 100.0, furnace.heater_on)
            )
        return self.physics.frame(self.codec, *self._measured)

    def _transmit(self, now: float, dt: float) -> None:
        frames = self.faults.babble(dt)
        for kind in self.schedule.due(now):
            if kind in self.UNSENT or (kind is PhysicsTelemetry and self.faults.silent):
                continue
            counter = self._counters.get(kind)
            frames.append(self.codec.encode(self._frame(kind), counter.next() if counter is not None else 0))
        for frame in frames:
            out = self.faults.transmit(frame)
            if out is None:
                continue
            try:
                self.bus.send(out)
                self.frames_sent += 1
            except can.CanError as exc:
                self.tx_errors += 1
                log.debug("send failed: %s", exc)


def _lowest(flags: FaultFlag) -> FaultFlag:
    """The lowest set bit of a fault set (the first cause when several latch in one tick)."""
    value = int(flags)
    return FaultFlag(value & -value)


__all__ = ["MOVING", "IllegalNodeTransition", "Node"]
