"""The CiA 402 backend: two standard CANopen drives, one per motor, behind the drives boundary.

python-canopen's ``Network`` runs on the controller's own can.Bus without a
notifier thread of its own: the tick drains the bus through the boundary's
:class:`~millctl.protocol.BusReader` and hands every frame to
``Network.notify``, so TPDOs, heartbeats and EMCYs are judged in the tick with
their age, and the SDO client (on the worker of :mod:`.sdo_jobs`) gets its
answers from there. The two drives are reported to the controller as one
node (:mod:`.report`), so the controller judges them exactly as it judges the
millbus node: same confirmations, same escalations, same trips. With
``furnace = "millbus"`` the millbus furnace node is on a second CAN channel
(:mod:`.furnace_link`): every command, E-stop, heartbeat and setpoint goes to
it too, and its reports are merged into that one node (``has_furnace``).
"""

from __future__ import annotations

import logging
import math
import struct
from concurrent.futures import Future, ThreadPoolExecutor

import can
import canopen

from millctl.config.models import Cia402Mode, FurnaceBackend, MillConfig
from millctl.drives.base import DriveInfo, DrivesBackend, DrivesBatch, LimitsState
from millctl.drives.cia402.furnace_link import FurnaceLink
from millctl.drives.cia402.limits import drive_limits
from millctl.drives.cia402.report import DriveLink, Intent, NodeReport
from millctl.drives.cia402.sdo_jobs import PRODUCER_HEARTBEAT_MS, start_up, write_all
from millctl.drives.cia402.state402 import PowerMachine
from millctl.protocol import (
    Codec,
    Command,
    CommandCode,
    EStop,
    EStopSource,
    FaultFlag,
    Heartbeat,
    MillMessage,
    Setpoints,
    default_codec,
    open_bus,
)
from millctl.protocol import ControllerState as WireState
from millctl.safety import Envelope, RampPlanner, SpeedPoint, Trajectory

log = logging.getLogger(__name__)

NMT_OPERATIONAL = 0x05
"""The heartbeat state byte the controller produces (it is operational while it ticks)."""

UNHEARD_START_UP_S = 2.0
"""Drives not all heard by their heartbeat after this long (s) are configured anyway: SDO needs no heartbeat."""

STARTUP_RETRY_S = 5.0
"""A start-up a drive refused is tried again after this long (s; the refusal is in the drive's status detail)."""

DRIVE_HEARTBEAT_S = PRODUCER_HEARTBEAT_MS / 1000.0
"""The drives' own heartbeat period (s): 0x1017 as millctl writes it at start-up."""


class Cia402Drives(DrivesBackend):
    """Two CiA 402 drives on the controller's bus (``[drives] backend = "cia402"``)."""

    backend = "cia402"
    e2e = False  # CANopen carries no counter or CRC (docs/safety.md#cia-402-drives)
    has_furnace = False

    def __init__(self, config: MillConfig, bus: can.BusABC, envelope: Envelope, *,
                 furnace_bus: can.BusABC | None = None, codec: Codec | None = None) -> None:
        """``furnace_bus``: the furnace node's bus (None: opened from ``[drives.furnace_bus]`` when configured)."""
        super().__init__(bus)
        self.config = config
        self.envelope = envelope
        drives = config.drives
        self.controller_id = drives.controller_node_id
        self.network = canopen.Network(bus)
        interlock = config.interlock
        stale_s = max(interlock.stale_periods * 0.05, interlock.min_stale_s)
        self.links: dict[str, DriveLink] = {}
        for motor in ("rotary", "vibration"):
            drive = getattr(drives, motor)
            cia = drive.cia402
            assert cia is not None  # the config's validator requires it with backend = "cia402"
            node = self.network.add_node(cia.node_id, cia.eds)
            link = DriveLink(motor, drive, cia, node, PowerMachine(interlock.command_confirm_s, stale_s),
                             heartbeat_stale_s=max(3 * DRIVE_HEARTBEAT_S, interlock.min_stale_s))
            self.links[motor] = link
            self.network.subscribe(0x180 + cia.node_id, link.on_tpdo)
            self.network.subscribe(0x700 + cia.node_id, link.on_heartbeat)
            self.network.subscribe(0x80 + cia.node_id, link.on_emcy)
            for foreign in (0x200 + cia.node_id, 0x600 + cia.node_id):
                self.network.subscribe(foreign, self._on_foreign)
        for foreign in (0x000, 0x700 + self.controller_id):
            self.network.subscribe(foreign, self._on_foreign)
        self.report = NodeReport(list(self.links.values()), interlock.command_confirm_s,
                                 RampPlanner.from_config(config, envelope))
        self.furnace: FurnaceLink | None = None
        self._owns_furnace_bus = False
        if drives.furnace is FurnaceBackend.MILLBUS and drives.furnace_bus is not None:
            self._owns_furnace_bus = furnace_bus is None
            self.furnace = FurnaceLink(furnace_bus if furnace_bus is not None else open_bus(drives.furnace_bus),
                                       drives.furnace_bus, codec or default_codec(), interlock)
            self.report.furnace = self.furnace
            self.has_furnace = True
        self._jobs = ThreadPoolExecutor(max_workers=1, thread_name_prefix="cia402-sdo")
        self._startup: Future[list[str]] | None = None
        self._limits: Future[str] | None = None
        self._setpoint_period_s = config.timing.setpoint_period_s
        self._next_rpdo_s = -math.inf
        self._startup_retry_s = -math.inf
        self._first_periodic_s: float | None = None
        self._sent_words: dict[str, int] = {}

    # -- reading
    def _drain(self, now_s: float) -> DrivesBatch:
        batch = self.reader.drain()
        self.report.now_s = now_s
        if batch.estop:  # ID 0x000, millbus's E-stop, is CANopen's NMT: only the controller sends it
            self.report.second_sender(0x000, b"")
        for frame in batch.frames:
            if frame.is_extended_id or frame.is_remote_frame:
                continue
            self.network.notify(frame.arbitration_id, bytearray(frame.data), now_s)
        furnace = self.furnace.drain(now_s) if self.furnace is not None else []
        return DrivesBatch(self.report.emit(now_s) + furnace, batch.error_frames)

    def _on_foreign(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """A frame only the controller sends, heard on the bus: another sender (SAFETY 17 on CANopen)."""
        self.report.second_sender(can_id, bytes(data))

    def _describe(self) -> list[DriveInfo]:
        furnace = [self.furnace.info(self.report.now_s)] if self.furnace is not None else []
        return [link.info(self.report.now_s) for link in self.links.values()] + furnace

    def fault_detail(self) -> str:
        """The first cause the drives' report latched."""
        return self.report.cause

    # -- sending
    def _to_furnace(self, message: MillMessage) -> None:
        """Send to the furnace node too (a failed send is logged, and never keeps a frame from the drives)."""
        if self.furnace is not None:
            link = self.furnace
            self._guarded(f"furnace node {type(message).__name__}", lambda: link.send(message))

    def _command(self, code: CommandCode) -> None:
        self._to_furnace(Command(code))
        now = self.report.now_s
        if code is CommandCode.ARM:
            self.report.intent = Intent.ENABLED
        elif code is CommandCode.DISARM:
            self.report.disarm()
        elif code is CommandCode.STOP:
            self.report.stop(now)
        elif code is CommandCode.RESET:
            self.report.reset(now)
        self._steer(now)
        self._send_rpdos(now)

    def _estop(self, source: EStopSource) -> None:
        self._to_furnace(EStop(source))
        now = self.report.now_s
        self.report.estop(now)
        self._steer(now)
        self._send_rpdos(now)

    def _heartbeat(self, state: WireState, challenge: int) -> None:
        if self.furnace is not None:  # the furnace node's own challenge, not the merged report's
            self._to_furnace(Heartbeat(state, self.furnace.challenge))
        self.network.send_message(0x700 + self.controller_id, bytes([NMT_OPERATIONAL]))

    def _setpoints(self, speeds: SpeedPoint, furnace_c: float, heater_on: bool) -> None:
        self._to_furnace(Setpoints(rotary_rpm=0.0, vibration_rpm=0.0, furnace_c=furnace_c, heater_on=heater_on))
        self.report.setpoints(speeds.omega_r_rpm, speeds.omega_v_rpm)
        self._send_rpdos(self.report.now_s)

    def _periodic(self, now_s: float) -> None:
        self.report.now_s = now_s
        restarted = [link for link in self.links.values() if link.restarted]
        if restarted and self.report.started:  # it lost its configuration: latched, and configured again
            for link in restarted:
                self.report.latch(FaultFlag.DRIVE, f"{link.name} restarted (boot-up heard): it lost its "
                                  "configuration and is configured again; reset to go on")
            self.report.started = False
        if self._first_periodic_s is None:
            self._first_periodic_s = now_s
        unheard_s = now_s - self._first_periodic_s  # a drive whose 0x1017 is 0 sends no heartbeat until configured
        if (self._startup is None and not self.report.started and now_s >= self._startup_retry_s
                and (self.report.all_heard(now_s) or unheard_s >= UNHEARD_START_UP_S)):
            self._startup = self._jobs.submit(self._start_up)
        if self._startup is not None and self._startup.done():
            refusals = [r for r in self._startup.result() if r]
            self._startup = None
            if refusals:  # shown in each drive's detail (status, TUI); tried again after a pause
                log.warning("CiA 402 start-up refused, trying again in %.0f s: %s", STARTUP_RETRY_S,
                            "; ".join(refusals))
                self._startup_retry_s = now_s + STARTUP_RETRY_S
            else:
                self.report.started_up()
        self._steer(now_s)
        if now_s >= self._next_rpdo_s or any(
            self._sent_words.get(m) != link.power.controlword(now_s) for m, link in self.links.items()
        ):
            self._send_rpdos(now_s)

    def _steer(self, now_s: float) -> None:
        """Each drive's wanted power state from the report's intent; the limits hold the enabling."""
        self.report.steer(now_s, limits_ready=self.limits_state() is LimitsState.READY,
                          limits_error=self.limits_error)

    def _send_rpdos(self, now_s: float) -> None:
        """RPDO1 to each drive: controlword + target velocity (sent every setpoint period in every state)."""
        self._next_rpdo_s = now_s + self._setpoint_period_s
        for motor, link in self.links.items():
            word = link.power.controlword(now_s)
            self._sent_words[motor] = word
            velocity = self.report.velocity_units(link, now_s)
            if link.cia.mode is Cia402Mode.VELOCITY:
                data = struct.pack("<Hh", word, max(min(velocity, 32767), -32768))
            else:
                data = struct.pack("<Hi", word, velocity)
            self.network.send_message(0x200 + link.cia.node_id, data)

    # -- the SDO work
    def _start_up(self) -> list[str]:
        consumer_ms = max(round(self.config.timing.watchdog_timeout_s * 1000), 1)
        results = []
        for link in self.links.values():
            refusal, identity = start_up(link.motor, link.node, link.cia.mode, self.controller_id, consumer_ms)
            link.identity, link.startup_error = identity, refusal
            results.append(refusal)
        return results

    def _prepare_move(self, move: Trajectory | None) -> None:
        plan = {m: drive_limits(m, link.drive, link.cia, self.envelope, move) for m, link in self.links.items()}
        self._limits = self._jobs.submit(self._write_limits, plan)

    def _write_limits(self, plan: dict[str, list]) -> str:  # type: ignore[type-arg]
        for motor, limits in plan.items():
            refusal = write_all(motor, self.links[motor].node, limits)
            if refusal:
                return refusal
        return ""

    def limits_state(self) -> LimitsState:
        """READY once every drive holds the limits written last; REFUSED on a differing read-back."""
        if self._limits is None:
            return LimitsState.PENDING
        if not self._limits.done():
            return LimitsState.PENDING
        return LimitsState.REFUSED if self._limits.result() else LimitsState.READY

    @property
    def limits_error(self) -> str:
        """The refusal of the last limits (object, written and read values, drive)."""
        if self._limits is None or not self._limits.done():
            return ""
        return self._limits.result()

    def close(self) -> None:
        """Stop the SDO worker (a transfer under way ends at its timeout); the bus is the caller's.

        The furnace node's bus is shut down when this backend opened it.
        """
        self._jobs.shutdown(wait=False, cancel_futures=True)
        if self.furnace is not None and self._owns_furnace_bus:
            self.furnace.bus.shutdown()


__all__ = ["Cia402Drives"]
