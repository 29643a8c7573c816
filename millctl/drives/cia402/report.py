"""The two CiA 402 drives reported to the controller as one node: what each drive's frames say, and the node it makes.

Each :class:`DriveLink` keeps one drive's latest TPDO (statusword and
velocity actual, with the time it arrived), its heartbeat and its first EMCY.
:class:`NodeReport` turns both into the node-shaped reports the controller
judges (:class:`~millctl.protocol.NodeStatus`, :class:`~millctl.protocol.DriveTelemetry`),
one of each when both drives have sent a fresh TPDO: DISABLED until both are
OPERATION ENABLED after an ARM, ARMED / RUNNING / STOPPING as the millbus node
reports them, FAULT with the first cause latched until a RESET (a drive's
FAULT or EMCY, a quick stop the drive took by itself, a step not confirmed in
time, a stale heartbeat, a second sender, a limit not held).
"""

from __future__ import annotations

import enum
import math
import struct
from dataclasses import dataclass

import canopen

from millctl.config.models import Cia402Drive, Cia402Mode, Drive
from millctl.drives.base import DriveInfo
from millctl.drives.cia402.furnace_link import FurnaceLink
from millctl.drives.cia402.sdo_jobs import Identity
from millctl.drives.cia402.state402 import (
    QUICK_STOP_OPTION,
    Power,
    PowerMachine,
    quick_stop_complete,
    quick_stop_shown,
)
from millctl.protocol import NO_FAULTS, Decoded, DriveTelemetry, FaultCode, FaultFlag, NodeState, NodeStatus
from millctl.safety import RampPlanner, SpeedPoint, Trajectory

STANDSTILL_RPM = 1.0
"""A drive slower than this is at standstill (rpm; the controller's own bound)."""

NMT_NAMES = {0x00: "BOOT-UP", 0x04: "STOPPED", 0x05: "OPERATIONAL", 0x7F: "PRE-OPERATIONAL"}


class Intent(enum.StrEnum):
    """What the controller last asked of the drives' power stage."""

    DISABLED = "disabled"
    ENABLED = "enabled"


@dataclass
class DriveLink:
    """One drive as its frames show it (times in s, controller clock)."""

    motor: str
    drive: Drive
    cia: Cia402Drive
    node: canopen.RemoteNode
    power: PowerMachine
    heartbeat_stale_s: float
    target_units: int = 0
    velocity_units: int | None = None
    tpdo_s: float = -math.inf
    heartbeat_s: float = -math.inf
    nmt_state: int | None = None
    emcy: str = ""
    restarted: bool = False
    identity: Identity | None = None
    startup_error: str = ""
    """Why its last start-up was refused ("" when it was not)."""

    @property
    def name(self) -> str:
        """``rotary drive (node 2)``."""
        return f"{self.motor} drive (node {self.cia.node_id})"

    def on_tpdo(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """TPDO1: statusword (u16) + velocity actual (i32 in profile velocity, i16 in velocity mode)."""
        layout = "<Hh" if self.cia.mode is Cia402Mode.VELOCITY else "<Hi"
        if len(data) < struct.calcsize(layout):
            return
        statusword, velocity = struct.unpack_from(layout, data)
        self.power.observe(statusword, timestamp)
        self.velocity_units = velocity
        self.tpdo_s = timestamp

    def on_heartbeat(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """The drive's heartbeat (0x700 + ID): its NMT state; a boot-up after the first means it restarted."""
        if not data:
            return
        state = data[0] & 0x7F
        if state == 0x00 and self.nmt_state is not None:
            self.restarted = True
        self.nmt_state = state
        self.heartbeat_s = timestamp

    def on_emcy(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """EMCY (0x80 + ID): the first error code is kept until a reset (code 0 is "error reset")."""
        if len(data) < 3:
            return
        code, register = struct.unpack_from("<HB", data)
        if code and not self.emcy:
            self.emcy = f"EMCY 0x{code:04X} (error register 0x{register:02X})"

    def measured_rpm(self) -> float:
        """The mill speed the latest velocity actual stands for (rpm; 0 before the first)."""
        return 0.0 if self.velocity_units is None else self.cia.mill_rpm(self.velocity_units)

    def info(self, now_s: float) -> DriveInfo:
        """The drive for the operator: CiA 402 state, NMT state, heartbeat age, identity, EMCY."""
        state = self.power.believed(now_s)
        nmt = NMT_NAMES.get(self.nmt_state, f"0x{self.nmt_state:02X}") if self.nmt_state is not None else "unheard"
        parts = [f"NMT {nmt}"]
        if not math.isinf(self.heartbeat_s):
            parts.append(f"heartbeat {now_s - self.heartbeat_s:.2f} s ago")
        if self.identity is not None:
            parts.append(str(self.identity))
        if state is not None and self.power.wanted is Power.QUICK_STOP_ACTIVE:
            done = quick_stop_complete(state, QUICK_STOP_OPTION, abs(self.measured_rpm()) < STANDSTILL_RPM)
            parts.append("quick stop complete" if done else "quick stop under way")
        if self.emcy:
            parts.append(self.emcy)
        if self.startup_error:
            parts.append(f"start-up refused: {self.startup_error}")
        return DriveInfo(self.motor, str(state) if state is not None else "unknown", self.cia.node_id,
                         "; ".join(parts))


@dataclass
class NodeReport:
    """Both drives as one node, with the first cause of a fault latched until RESET."""

    links: list[DriveLink]
    confirm_s: float
    planner: RampPlanner
    """Plans the controlled stop inside the envelope, as the millbus node does (:meth:`RampPlanner.plan_stop`)."""
    now_s: float = 0.0
    intent: Intent = Intent.DISABLED
    started: bool = False
    stopping: bool = False
    estop_latched: bool = False
    cause: str = ""
    bits: FaultFlag = NO_FAULTS
    first: FaultCode = FaultCode.NONE
    _running: bool = False
    _armed_once: bool = False
    _emitted_s: float = -math.inf
    _challenge: int = 0
    _stop_plan: Trajectory | None = None
    _stop_start_s: float = 0.0
    furnace: FurnaceLink | None = None
    """The millbus furnace node on its own channel, merged into this node (None: cold milling)."""

    def latch(self, flag: FaultFlag, cause: str) -> None:
        """A fault: the first cause is kept, every flag added."""
        if not self.bits:
            self.first = FaultCode.of(flag)
            self.cause = cause
        self.bits |= flag

    def all_heard(self, now_s: float) -> bool:
        """Every drive has sent a heartbeat (it is on the bus and can be configured)."""
        return all(not math.isinf(link.heartbeat_s) for link in self.links)

    def started_up(self) -> None:
        """Both drives configured and started: their reports count from now."""
        self.started = True
        for link in self.links:
            link.restarted = False

    def second_sender(self, can_id: int, data: bytes) -> None:
        """A frame only the controller sends was heard: someone else commands the drives."""
        self.latch(FaultFlag.E2E_LINK, f"second sender: frame 0x{can_id:03X} [{data.hex()}] heard on the bus, "
                   "which only the controller sends (docs/safety.md#cia-402-drives)")

    def stop(self, now_s: float) -> None:
        """Controlled stop: the planned stop inside the envelope from the present targets, then ARMED at standstill."""
        if self.intent is Intent.ENABLED and not self.stopping:
            rotary, vibration = (link.cia.mill_rpm(link.target_units) for link in self.links)
            self._stop_plan, self._stop_start_s = self.planner.plan_stop(SpeedPoint(rotary, vibration)), now_s
        self.stopping = self.intent is Intent.ENABLED
        for link in self.links:
            link.target_units = 0

    def velocity_units(self, link: DriveLink, now_s: float) -> int:
        """The target velocity RPDO1 carries now (drive units): the stop's ramp while stopping, else the target."""
        if link.power.wanted is not Power.OPERATION_ENABLED or self.estop_latched or self.bits:
            return 0
        if self.stopping and self._stop_plan is not None:
            point = self._stop_plan.at(now_s - self._stop_start_s)
            return link.cia.wire_velocity(point.omega_r_rpm if link is self.links[0] else point.omega_v_rpm)
        return link.target_units

    def estop(self, now_s: float) -> None:
        """E-stop: quick stop to both drives until both statuswords show it."""
        self.estop_latched = True
        for link in self.links:
            link.target_units = 0

    def reset(self, now_s: float) -> None:
        """Clear the latches and head for SWITCH ON DISABLED (fault reset edges where a drive is in FAULT)."""
        self.cause, self.bits, self.first = "", NO_FAULTS, FaultCode.NONE
        self.estop_latched = self.stopping = self._running = self._armed_once = False
        self._stop_plan = None
        self.intent = Intent.DISABLED
        for link in self.links:
            link.emcy = ""
            link.target_units = 0
        if self.furnace is not None:
            self.furnace.forget()

    def disarm(self) -> None:
        """DISARM: the drives head for SWITCH ON DISABLED, and the next ARM enables them anew.

        Until a drive has reached OPERATION ENABLED under this ARM, not being
        there is the enabling under way, not a drive that left it by itself
        (seen: arm, disarm, arm, set speeds tripped on the second ARM's
        READY TO SWITCH ON).
        """
        self.intent = Intent.DISABLED
        self._armed_once = False

    def setpoints(self, rotary_rpm: float, vibration_rpm: float) -> None:
        """The checked pair, as each drive's target (ignored unless enabled and not stopping or faulted)."""
        if self.intent is not Intent.ENABLED or self.stopping or self.bits or self.estop_latched:
            return
        for link, rpm in zip(self.links, (rotary_rpm, vibration_rpm), strict=True):
            link.target_units = link.cia.wire_velocity(rpm)

    def steer(self, now_s: float, *, limits_ready: bool, limits_error: str) -> None:
        """Each drive's wanted power state: QUICK STOP on E-stop; enabled only once the limits hold."""
        if limits_error and self.intent is Intent.ENABLED:
            self.latch(FaultFlag.DRIVE, limits_error)
        for link in self.links:
            if self.estop_latched:
                wanted = Power.QUICK_STOP_ACTIVE
            elif self.intent is Intent.ENABLED and (link.power.wanted is Power.OPERATION_ENABLED or (
                    limits_ready and not self.bits)):
                wanted = Power.OPERATION_ENABLED
            elif self.intent is Intent.ENABLED and self.bits:
                wanted = link.power.wanted  # a fault stops on the ramps, enabled, until RESET
            else:
                wanted = Power.SWITCH_ON_DISABLED
            link.power.want(wanted, now_s)

    def emit(self, now_s: float) -> list[Decoded]:
        """One NodeStatus and one DriveTelemetry when both drives have sent a fresh TPDO since the last."""
        if not self.started or any(link.tpdo_s <= self._emitted_s for link in self.links):
            return []
        self._emitted_s = now_s
        self._judge(now_s)
        self._challenge = (self._challenge + 1) & 0xFFFF
        status = NodeStatus(self._state(), self.bits, self.first, challenge=self._challenge)
        rotary, vibration = (link.measured_rpm() for link in self.links)
        return [
            Decoded(NodeStatus, status, None, True, 0x180 + self.links[0].cia.node_id, now_s),
            Decoded(DriveTelemetry, DriveTelemetry(rotary, vibration), None, True,
                    0x180 + self.links[1].cia.node_id, now_s),
        ]

    def _judge(self, now_s: float) -> None:
        """Latch what the drives' frames (and the furnace node's reports) say went wrong."""
        if self.furnace is not None:
            for flag, cause in self.furnace.faults(now_s, estop_commanded=self.estop_latched):
                self.latch(flag, cause)
        for link in self.links:
            state = link.power.believed(now_s)
            if link.emcy:
                self.latch(FaultFlag.DRIVE, f"{link.name}: {link.emcy}")
            age_s = now_s - link.heartbeat_s
            if age_s > link.heartbeat_stale_s:
                self.latch(FaultFlag.DRIVE, f"{link.name} heartbeat stale: age {age_s:.2f} s > bound "
                           f"{link.heartbeat_stale_s:.2f} s (0x1017)")
            if state in (Power.FAULT, Power.FAULT_REACTION_ACTIVE):
                self.latch(FaultFlag.DRIVE, f"{link.name} in {state} (statusword 0x{link.power.statusword or 0:04X})")
            elif state is Power.QUICK_STOP_ACTIVE and not self.estop_latched:
                self.latch(FaultFlag.WATCHDOG, f"{link.name} quick-stopped by itself: its heartbeat consumer "
                           "(0x1016) lost the controller's heartbeat, or its own protection acted")
            elif (self._armed_once and self.intent is Intent.ENABLED and state is not Power.OPERATION_ENABLED
                  and not self.estop_latched):
                self.latch(FaultFlag.DRIVE, f"{link.name} left OPERATION ENABLED by itself (now {state})")
            stuck = link.power.stuck(now_s)
            if stuck:
                self.latch(FaultFlag.DRIVE, f"{link.name}: {stuck}")

    def _state(self) -> NodeState:
        now = self.now_s
        states = [link.power.believed(now) for link in self.links]
        furnace_shown = self.furnace is None or self.furnace.estop_shown()
        if self.estop_latched and furnace_shown and all(s is not None and quick_stop_shown(s) for s in states):
            self.latch(FaultFlag.ESTOP, "E-stop: both drives in quick stop" +
                       (", the furnace node E-stopped" if self.furnace is not None else ""))
        if self.bits:
            return NodeState.FAULT
        drives = self._drives_state(states)
        return drives if self.furnace is None else self._with_furnace(drives)

    def _with_furnace(self, drives: NodeState) -> NodeState:
        """The drives' state merged with the furnace node's: ARMED only when both are, DISABLED when both are.

        A furnace node that leaves ARMED by itself (a restart) makes the mill
        DISABLED, which the controller trips on as for the millbus node; one
        armed by another sender makes it ARMED, which the controller did not
        command (docs/deployment.md#a-furnace-beside-the-drives-a-second-can-channel).
        """
        furnace = self.furnace.state if self.furnace is not None else None
        moving = furnace in (NodeState.ARMED, NodeState.RUNNING, NodeState.STOPPING)
        if self.estop_latched:
            return drives
        if drives is NodeState.DISABLED:
            return NodeState.ARMED if moving and self.intent is Intent.DISABLED else NodeState.DISABLED
        if self.intent is Intent.ENABLED and not moving:
            return NodeState.DISABLED
        return drives

    def _drives_state(self, states: list[Power | None]) -> NodeState:
        """Both drives as one node state (no fault latched)."""
        enabled = all(s is Power.OPERATION_ENABLED for s in states)
        if self.intent is Intent.DISABLED:
            return NodeState.ARMED if any(s is Power.OPERATION_ENABLED for s in states) else NodeState.DISABLED
        if not enabled:
            return NodeState.DISABLED
        self._armed_once = True
        at_rest = all(abs(link.measured_rpm()) < STANDSTILL_RPM for link in self.links)
        if self.stopping:
            if not at_rest:
                return NodeState.STOPPING
            self.stopping = self._running = False
            self._stop_plan = None
            return NodeState.ARMED
        if any(link.target_units for link in self.links):
            self._running = True
        elif at_rest:
            self._running = False
        return NodeState.RUNNING if self._running else NodeState.ARMED


__all__ = ["DriveLink", "Intent", "NodeReport"]
