"""The simulated CiA 402 mill: one :class:`~firmware_sim.cia402.drive.SimDrive` per motor on one can.Bus.

:meth:`Cia402Mill.tick` is the drives' firmware cycle, stepped from the injected
clock like :meth:`firmware_sim.node.Node.tick`: it reads every waiting frame
(heartbeats to the consumers, RPDO1 to each drive in NMT OPERATIONAL, SDO and
NMT to canopen's LocalNode, SimFault frames to the fault injector), advances
profiles and motors (the millbus node's drive dynamics, sub-stepped at
``timing.node_tick_s``), runs each drive's protection and heartbeat consumer,
and sends what is due: boot-up, heartbeats (0x1017), TPDO1 at its event timer
and on a statusword change, EMCY. canopen's Network sends through
:class:`_FaultyBus`, so an injected loss, corruption, babble or silence acts on
every frame the drives send (SDO answers included). No thread: nothing runs
between ticks. The furnace is "none" (cold milling, docs/protocol.md "CiA 402").
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import can
import canopen
import numpy as np
from canopen.nmt import NmtSlave

from firmware_sim.cia402.drive import SimDrive
from firmware_sim.drives import DrivePair
from firmware_sim.faults import FaultInjector
from firmware_sim.furnace import FurnaceModel
from millctl.clock import Clock
from millctl.config.loader import GENERIC_EDS, packaged_file
from millctl.config.models import Cia402Drive, DriveBackend, MillConfig
from millctl.errors import ConfigError, InvalidInputError
from millctl.protocol import ProtocolError, SimFault, default_codec

log = logging.getLogger(__name__)

SIM_FAULT_ID = 0x700
"""SimFault frames (config/millbus.dbc) keep their identifier: 0x700 is no CANopen node's heartbeat (IDs 1–127)."""
DRAIN_MAX_FRAMES = 2000
"""At most this many frames are read in one tick (a flood cannot hold the drives' cycle)."""
NMT_RESET_NODE = 0x81
NMT_RESET_COMMUNICATION = 0x82


class _TickedNmt(NmtSlave):
    """canopen's NMT slave without its heartbeat thread: the mill's tick sends the heartbeat (0x1017)."""

    def start_heartbeat(self, heartbeat_time_ms: int) -> None:
        self._heartbeat_time_ms = heartbeat_time_ms

    def stop_heartbeat(self) -> None:
        self._heartbeat_time_ms = 0


class _FaultyBus(can.BusABC):
    """The drives' side of the bus: what canopen sends passes the fault injector (loss, corruption, silence)."""

    def __init__(self, bus: can.BusABC, faults: FaultInjector) -> None:
        self._bus = bus
        self._faults = faults
        self.frames_sent = 0
        self.tx_errors = 0
        self.channel_info = f"cia402 drives on {bus.channel_info}"

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        out = self._faults.transmit(msg)
        if out is None:
            return
        try:
            self._bus.send(out, timeout)
            self.frames_sent += 1
        except can.CanError as exc:
            self.tx_errors += 1
            log.debug("send failed: %s", exc)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return None, False  # the mill reads its real bus itself, in its tick


def eds_path(cia: Cia402Drive) -> Path:
    """The drive's EDS: the configured file, else the shipped generic one."""
    return Path(cia.eds) if cia.eds else packaged_file(GENERIC_EDS)


class Cia402Mill:
    """Both simulated CiA 402 drives on one bus, with the millbus node's dynamics and fault injection."""

    def __init__(
        self, config: MillConfig, bus: can.BusABC, clock: Clock, *, fault_injection: bool = False, seed: int = 0
    ) -> None:
        drives = config.drives
        if drives.backend is not DriveBackend.CIA402:
            raise InvalidInputError(
                f'[drives] backend = "{drives.backend.value}": the simulated CiA 402 drives need backend = "cia402" '
                "(config/mill-cia402.toml; docs/protocol.md, \"CiA 402\")"
            )
        self.config = config
        self.bus = bus
        self.clock = clock
        self.codec = default_codec()
        self.pair = DrivePair(config, np.random.default_rng(seed))
        self.furnace = FurnaceModel(config.furnace, config.timing.node_tick_s)  # cold: never commanded
        self.faults = FaultInjector(config, self.pair, self.furnace, enabled=fault_injection, seed=seed)
        self.out = _FaultyBus(bus, self.faults)
        self.network = canopen.Network(self.out)
        interlock = config.interlock
        self.drives: dict[str, SimDrive] = {}
        for name, drive, model, reference in (
            ("rotary", drives.rotary, self.pair.rotary, self.pair.rotary_ref),
            ("vibration", drives.vibration, self.pair.vibration, self.pair.vibration_ref),
        ):
            cia = drive.cia402
            assert cia is not None  # Drives' validator requires it with backend = "cia402"
            try:
                od = canopen.import_od(str(eds_path(cia)), cia.node_id)
            except Exception as exc:  # canopen raises whatever its parser meets
                raise ConfigError(
                    str(eds_path(cia)), [f"drives.{name}.cia402.eds: not a readable EDS ({type(exc).__name__}: {exc})"]
                ) from exc
            sim = SimDrive(name, drive, cia, od, model, reference, tolerance_rpm=interlock.measurement_tolerance_rpm,
                           debounce=interlock.debounce_samples)
            _ticked_nmt(sim.node)
            self.network.add_node(sim.node)
            self.drives[name] = sim
        self._max_step_s = config.timing.node_tick_s
        self._last_tick_s: float | None = None
        self._booted: set[str] = set()
        self._heartbeat_s: dict[str, float] = {}
        self._tpdo_s: dict[str, float] = {}
        self._tpdo_status: dict[str, int] = {}
        self.tick_count = 0
        self.frames_read = 0
        self.malformed = 0
        log.info("simulated CiA 402 drives: %s", "; ".join(d.describe() for d in self.drives.values()))

    def close(self) -> None:
        """Nothing runs between ticks; the bus belongs to the caller."""

    # -- views ------------------------------------------------------------------------------------------------

    @property
    def true_speeds_rpm(self) -> tuple[float, float]:
        """The rotors' true (ω_r, ω_v) (rpm)."""
        return self.pair.rotary.speed_rpm, self.pair.vibration.speed_rpm

    @property
    def measured_speeds_rpm(self) -> tuple[float, float]:
        """The last sensor readings (ω_r, ω_v) (rpm), as the drives report them."""
        return self.pair.rotary.measured_rpm, self.pair.vibration.measured_rpm

    @property
    def at_standstill(self) -> bool:
        """Both drives at rest with no demand."""
        return all(d.at_standstill for d in self.drives.values())

    @property
    def heater_on(self) -> bool:
        """Cold milling: there is no heater."""
        return False

    # -- the tick ------------------------------------------------------------------------------------------------

    def tick(self) -> None:
        """One firmware cycle of both drives: frames in, profiles and motors, protection, frames out."""
        now = self.clock.now()
        dt = 0.0 if self._last_tick_s is None else max(now - self._last_tick_s, 0.0)
        self._last_tick_s = now
        self._boot_once()
        for _ in range(DRAIN_MAX_FRAMES):
            msg = self.bus.recv(timeout=0.0)
            if msg is None:
                break
            self._receive(msg, now)
        if dt > 0.0:
            steps = max(1, math.ceil(dt / self._max_step_s - 1e-9))
            for _ in range(steps):
                for drive in self.drives.values():
                    drive.step(dt / steps, now)
        for drive in self.drives.values():
            drive.supervise(dt, now)
        for frame in self.faults.babble(dt):
            self.out.send(frame)
        for name, drive in self.drives.items():
            self._heartbeat(name, drive, now)
            self._tpdo(name, drive, now)
        self.tick_count += 1

    def _boot_once(self) -> None:
        for name, drive in self.drives.items():
            if name in self._booted:
                continue
            self._booted.add(name)
            drive.boot()
            self.out.send(can.Message(arbitration_id=0x700 + drive.cia.node_id, data=b"\x00", is_extended_id=False))
            drive.node.nmt.state = "PRE-OPERATIONAL"

    def _receive(self, msg: can.Message, now: float) -> None:
        if msg.is_error_frame or msg.is_extended_id:
            return
        self.frames_read += 1
        cob_id, data = msg.arbitration_id, bytes(msg.data)
        if cob_id == SIM_FAULT_ID:
            self._sim_fault(msg)
            return
        if 0x701 <= cob_id <= 0x77F and not msg.is_remote_frame:
            for drive in self.drives.values():
                drive.on_heartbeat(cob_id - 0x700, now)
        for drive in self.drives.values():
            if drive.node.nmt.state == "OPERATIONAL" and cob_id == _pdo_cob_id(drive, 0x1400):
                _receive_rpdo(drive, data)
        if msg.is_remote_frame:
            return
        self.network.notify(cob_id, bytearray(data), now)
        if cob_id == 0 and len(data) >= 2:
            self._nmt_reset(data[0], data[1])

    def _sim_fault(self, msg: can.Message) -> None:
        try:
            decoded = self.codec.decode(msg)
        except ProtocolError as exc:
            self.malformed += 1
            log.info("malformed SimFault frame: %s", exc)
            return
        if isinstance(decoded.message, SimFault):
            self.faults.handle(decoded.message)

    def _nmt_reset(self, command: int, node_id: int) -> None:
        if command not in (NMT_RESET_NODE, NMT_RESET_COMMUNICATION):
            return
        for name, drive in self.drives.items():
            if node_id not in (0, drive.cia.node_id):
                continue
            store = drive.node.data_store
            for index in [i for i in store if command == NMT_RESET_NODE or i < 0x2000]:
                del store[index]
            self._booted.discard(name)
            self._tpdo_s.pop(name, None)
            self._heartbeat_s.pop(name, None)
            if command == NMT_RESET_NODE:
                drive.state = drive.state.__class__.NOT_READY_TO_SWITCH_ON
                drive.demand_rpm = 0.0
            drive.store(0x1018, 4, drive.cia.node_id)
            drive.node.nmt._state = 0  # INITIALISING until the boot-up of the next tick (canopen's own field)
        self._boot_once()

    # -- transmit -----------------------------------------------------------------------------------------------

    def _heartbeat(self, name: str, drive: SimDrive, now: float) -> None:
        period_s = drive.value(0x1017) / 1000.0
        if period_s <= 0.0:
            return
        last = self._heartbeat_s.get(name)
        if last is not None and now - last < period_s:
            return
        self._heartbeat_s[name] = now if last is None or now - last > 2 * period_s else last + period_s
        state = drive.node.nmt._state  # canopen's NMT state byte (0, 4, 5 or 127), what the heartbeat carries
        self.out.send(can.Message(arbitration_id=0x700 + drive.cia.node_id, data=bytes([state]),
                                  is_extended_id=False))

    def _tpdo(self, name: str, drive: SimDrive, now: float) -> None:
        if drive.node.nmt.state != "OPERATIONAL":
            return
        cob_id = _pdo_cob_id(drive, 0x1800)
        if cob_id is None:
            return
        period_s = drive.value(0x1800, 5) / 1000.0
        inhibit_s = drive.value(0x1800, 3) / 10_000.0
        last = self._tpdo_s.get(name)
        changed = self._tpdo_status.get(name) != drive.statusword
        due = last is None or (period_s > 0.0 and now - last >= period_s - 1e-9)
        if not (due or (changed and last is not None and now - last >= inhibit_s)):
            return
        self._tpdo_s[name] = now
        self._tpdo_status[name] = drive.statusword
        self.out.send(can.Message(arbitration_id=cob_id, data=_tpdo_payload(drive), is_extended_id=False))

    def shutdown_stop(self) -> None:
        """The process is ending: a quick stop on every drive that is enabled."""
        for drive in self.drives.values():
            drive.apply_controlword(drive.controlword & ~0x0004 & ~0x0080)


def _ticked_nmt(node: canopen.LocalNode) -> None:
    """Give the LocalNode an NMT slave without a heartbeat thread (before it joins the network)."""
    old = node.nmt
    node._write_callbacks.remove(old.on_write)  # canopen keeps no public way to replace the NMT slave
    assert node.id is not None
    node.nmt = _TickedNmt(node.id, node)
    node.add_write_callback(node.nmt.on_write)  # type: ignore[no-untyped-call]


def _pdo_cob_id(drive: SimDrive, comm_index: int) -> int | None:
    """A PDO's COB-ID from its communication parameter (None while bit 31, "not valid", is set)."""
    entry = drive.value(comm_index, 1)
    return None if entry & 0x8000_0000 else entry & 0x7FF


def _mapping(drive: SimDrive, map_index: int) -> list[tuple[int, int, int]]:
    """A PDO's mapping: (index, subindex, length in bytes) per mapped object."""
    count = drive.value(map_index, 0)
    entries = (drive.value(map_index, sub) for sub in range(1, count + 1))
    return [(e >> 16, (e >> 8) & 0xFF, (e & 0xFF) // 8) for e in entries if e >> 16]


def _receive_rpdo(drive: SimDrive, data: bytes) -> None:
    """Write RPDO1's mapped objects into the drive (a controlword acted on); a short frame is dropped."""
    mapping = _mapping(drive, 0x1600)
    if len(data) < sum(size for _, _, size in mapping):
        log.info("%s drive: RPDO1 of %d bytes, mapping needs %d: dropped", drive.name, len(data),
                 sum(size for _, _, size in mapping))
        return
    offset = 0
    for index, subindex, size in mapping:
        raw = data[offset:offset + size]
        offset += size
        var = drive.od_var(index, subindex)
        if index == 0x6040:
            drive.store(index, subindex, int(var.decode_raw(raw)))
            drive.apply_controlword(int(var.decode_raw(raw)))
        else:
            drive.node.data_store.setdefault(index, {})[subindex] = raw


def _tpdo_payload(drive: SimDrive) -> bytes:
    """TPDO1's data: its mapped objects as the drive holds them now."""
    return b"".join(drive.node.get_data(index, subindex)[:size] for index, subindex, size in _mapping(drive, 0x1A00))


__all__ = ["DRAIN_MAX_FRAMES", "SIM_FAULT_ID", "Cia402Mill", "eds_path"]
