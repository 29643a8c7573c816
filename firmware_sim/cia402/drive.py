"""One simulated CiA 402 velocity drive: canopen's LocalNode with the drive's own profile, limits and protection.

The object dictionary is the EDS (``config/cia402-drive.eds`` or the one the
configuration names); canopen's LocalNode answers SDO and NMT from it. The
drive's behaviour on top, stepped by :meth:`SimDrive.step` from the injected
clock (docs/protocol.md, "CiA 402"):

* the power state machine of :mod:`firmware_sim.cia402.power`, driven by the
  controlword (RPDO1 or SDO);
* a velocity profile: the target (0x60FF, or 0x6042 in velocity mode) is
  limited to min(0x607F max profile velocity, 0x6080 max motor speed), the
  demand (0x606B) slews towards it at 0x6083/0x6084 and stops at 0x6085 on a
  quick stop and in the fault reaction; the motor (firmware_sim.drives.DriveModel,
  the millbus node's drive dynamics) follows the demand;
* heartbeat consumer 0x1016 sub1 (producer node ID << 16 | time in ms): a
  silent producer raises EMCY 0x8130 and the reaction 0x6007 (0 none, 1 fault,
  2 disable voltage, 3 quick stop);
* its own protection (the checks of firmware_sim.monitor per axis): stall
  (EMCY 0x8611), over-speed past 0x6080 (0x8400), implausible sensor (0x7305).

Velocities on the wire are drive units: mill rpm × gear_ratio × units_per_rpm; 0x6080 is in motor rpm.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import canopen
from canopen.emcy import EmcyProducer
from canopen.objectdictionary import ODVariable

from firmware_sim.cia402 import power
from firmware_sim.cia402.power import Command, PowerState
from firmware_sim.drives import DriveModel
from firmware_sim.monitor import _AxisCheck
from millctl.config.models import Cia402Drive, Drive
from millctl.protocol.messages import FaultFlag

log = logging.getLogger(__name__)

EMCY_HEARTBEAT = 0x8130
"""Life guard or heartbeat error (CiA 301)."""
EMCY_STALL = 0x8611
"""Following error: the motor does not follow the demand (CiA 402)."""
EMCY_OVERSPEED = 0x8400
"""Velocity speed controller: the motor turns faster than 0x6080 allows (CiA 402)."""
EMCY_SENSOR = 0x7305
"""Incremental sensor 1 fault (CiA 402)."""
ERROR_REGISTER_GENERIC = 1 << 0
ERROR_REGISTER_COMMUNICATION = 1 << 4
FAULT_REACTION_SLACK_S = 1.0
"""The fault reaction gives up waiting for standstill after its ramp's time plus this (s), and cuts the power."""
MAX_ABORT_REACTION = 3


@dataclass
class Limits:
    """The limits the controller wrote, in mill rpm and mill rpm/s (0 where unset)."""

    max_rpm: float
    accel_rpm_s: float
    decel_rpm_s: float
    quick_stop_rpm_s: float
    quick_stop_option: int
    abort_option: int


class SimDrive:
    """A CiA 402 drive on one motor: its LocalNode, power state, profile, heartbeat consumer and protection."""

    def __init__(
        self,
        name: str,
        drive: Drive,
        cia: Cia402Drive,
        od: canopen.ObjectDictionary,
        model: DriveModel,
        reference: DriveModel,
        *,
        tolerance_rpm: float,
        debounce: int,
    ) -> None:
        self.name = name
        self.drive = drive
        self.cia = cia
        self.node = canopen.LocalNode(cia.node_id, od)
        self.model = model
        """The motor as it turns (faults act on it)."""
        self.reference = reference
        """The same motor without faults: what it should do for the demand given (the stall check's reference)."""
        self.check = _AxisCheck(drive, tolerance_rpm, debounce)
        self.tolerance_rpm = tolerance_rpm
        self.state = PowerState.NOT_READY_TO_SWITCH_ON
        self.demand_rpm = 0.0
        """The profile's demand (mill rpm): what the speed loop is told."""
        self.controlword = 0
        self.error_code = 0
        """The latched fault's EMCY code (0 when none)."""
        self.heartbeat_lost = False
        self._last_producer_s: float | None = None
        self._reaction_started_s = 0.0
        self._reaction_bound_s = 0.0
        self._overspeed = 0
        self._lies: dict[tuple[int, int], int] = {}
        self.emcy_sent: list[int] = []
        """Every EMCY code sent (a reset is 0), oldest first."""
        self.node.add_write_callback(self._on_write)  # type: ignore[no-untyped-call]
        self.node.add_read_callback(self._on_read)  # type: ignore[no-untyped-call]
        self.store(0x1018, 4, cia.node_id)  # serial number: the node ID (each simulated drive its own)

    # -- object dictionary -------------------------------------------------------------------------------

    def od_var(self, index: int, subindex: int = 0) -> ODVariable:
        """The OD entry (index, subindex); a KeyError names it when the EDS lacks it."""
        obj = self.node.object_dictionary[index]
        var = obj if isinstance(obj, ODVariable) else obj[subindex]
        assert isinstance(var, ODVariable)
        return var

    def value(self, index: int, subindex: int = 0) -> int:
        """The present value of an integer object (the data store, else the EDS default)."""
        var = self.od_var(index, subindex)
        raw = self.node.data_store.get(index, {}).get(subindex)
        decoded = var.decode_raw(raw) if raw is not None else (var.default or 0)
        return int(decoded)

    def store(self, index: int, subindex: int, value: int, var: ODVariable | None = None) -> None:
        """Set an object as the drive itself does (no write callbacks, no access check)."""
        var = var if var is not None else self.od_var(index, subindex)
        self.node.data_store.setdefault(index, {})[subindex] = var.encode_raw(value)

    def lie_readback(self, index: int, subindex: int = 0, offset: int = 1) -> None:
        """Fault injection: SDO reads of (index, subindex) return the written value plus ``offset`` (0 ends the lie)."""
        if offset:
            self._lies[(index, subindex)] = offset
        else:
            self._lies.pop((index, subindex), None)

    def _on_read(self, *, index: int, subindex: int, od: ODVariable) -> int | None:
        offset = self._lies.get((index, subindex))
        if offset is None:
            return None
        return self.value(index, subindex) + offset

    def _on_write(self, *, index: int, subindex: int, od: ODVariable, data: bytes) -> None:
        if index == 0x6040:
            self.apply_controlword(int(od.decode_raw(data)))

    # -- scaling --------------------------------------------------------------------------------------------

    @property
    def mode(self) -> int:
        """The mode of operation the drive runs (0x6060: 3 profile velocity, 2 velocity)."""
        return self.value(0x6060)

    def _units_per_mill_rpm(self) -> float:
        return self.cia.gear_ratio * self.cia.units_per_rpm

    def limits(self) -> Limits:
        """The limits now in the object dictionary, in mill rpm (0x6080 is motor rpm, the others drive units)."""
        per_rpm = self._units_per_mill_rpm()
        max_rpm = min(self.value(0x607F) / per_rpm, self.value(0x6080) / self.cia.gear_ratio)
        return Limits(
            max_rpm=max_rpm,
            accel_rpm_s=self.value(0x6083) / per_rpm,
            decel_rpm_s=self.value(0x6084) / per_rpm,
            quick_stop_rpm_s=self.value(0x6085) / per_rpm,
            quick_stop_option=self.value(0x605A),
            abort_option=self.value(0x6007),
        )

    def target_rpm(self) -> float:
        """The commanded target (mill rpm) of the present mode; 0 in a mode the drive does not run."""
        if self.mode == 3:
            wire = self.value(0x60FF)
        elif self.mode == 2:
            wire = self.value(0x6042)
        else:
            return 0.0
        return wire / self._units_per_mill_rpm()

    # -- power state ---------------------------------------------------------------------------------------

    def boot(self) -> None:
        """Power-up: NOT READY TO SWITCH ON → SWITCH ON DISABLED (transitions 0, 1)."""
        self.state = PowerState.SWITCH_ON_DISABLED
        self.store(0x6061, 0, self.mode)
        self._publish()

    def apply_controlword(self, word: int) -> None:
        """Act on a controlword (from RPDO1 or an SDO write of 0x6040)."""
        command = power.decode(word, self.controlword)
        self.controlword = word
        if command is Command.FAULT_RESET:
            self._fault_reset()
            return
        before = self.state
        self.state = power.next_state(self.state, command)
        if self.state is PowerState.OPERATION_ENABLED and before is not PowerState.OPERATION_ENABLED:
            self.demand_rpm = self.model.speed_rpm  # the profile starts from the motor's speed (it may coast)
        if self.state is PowerState.QUICK_STOP_ACTIVE and self.limits().quick_stop_option == 0:
            self.state = PowerState.SWITCH_ON_DISABLED  # 0x605A = 0: disable the drive function at once
        if self.state is not before:
            log.info("%s drive %s → %s (%s)", self.name, before.value, self.state.value, command.value)
        self._publish()

    def _fault_reset(self) -> None:
        if self.state is not PowerState.FAULT:
            return
        if self.fault_cause_present() or not self.at_standstill:
            log.info("%s drive: fault reset refused, cause 0x%04X still present or not at rest", self.name,
                     self.error_code)
            return
        self.error_code = 0
        self.heartbeat_lost = False
        self.check = _AxisCheck(self.drive, self.tolerance_rpm, self.check.debounce)
        self._overspeed = 0
        self.state = PowerState.SWITCH_ON_DISABLED
        self.store(0x603F, 0, 0)
        self.store(0x1001, 0, 0)
        self._emcy(0, 0)
        log.info("%s drive: fault reset → SWITCH ON DISABLED", self.name)
        self._publish()

    def fault_cause_present(self) -> bool:
        """True while the latched fault's cause is still there (a fault reset needs it gone)."""
        model = self.model
        if self.error_code == EMCY_STALL:
            return model.stalled
        if self.error_code == EMCY_OVERSPEED:
            return model.runaway_rpm is not None
        if self.error_code == EMCY_SENSOR:
            return model.sensor_stuck_rpm is not None or model.sensor_noise_rpm is not None
        return False

    def raise_fault(self, code: int, register: int, reason: str, now_s: float) -> None:
        """Latch a fault: EMCY, error code, and the fault reaction (a quick-stop ramp, then FAULT)."""
        if self.error_code:
            return
        self.error_code = code
        self.store(0x603F, 0, code)
        self.store(0x1001, 0, register)
        self._emcy(code, register)
        log.warning("%s drive fault 0x%04X: %s", self.name, code, reason)
        if self.state in power.POWERED:
            self.state = PowerState.FAULT_REACTION_ACTIVE
            self._reaction_started_s = now_s
            rate = self._stop_rate(self.limits().quick_stop_rpm_s)
            self._reaction_bound_s = self.model.speed_rpm / rate + FAULT_REACTION_SLACK_S
        else:
            self.state = PowerState.FAULT
        self._publish()

    def _emcy(self, code: int, register: int) -> None:
        self.emcy_sent.append(code)
        emcy: EmcyProducer = self.node.emcy
        try:
            emcy.send(code, register) if code else emcy.reset(register)
        except Exception as exc:  # a full or failed bus: the fault is latched all the same (can.CanError)
            log.debug("%s drive: EMCY 0x%04X not sent: %s", self.name, code, exc)

    # -- heartbeat consumer -------------------------------------------------------------------------------------

    def consumer(self) -> tuple[int, float]:
        """The heartbeat consumer entry 0x1016 sub1: (producer node ID, time s); time 0 = off."""
        entry = self.value(0x1016, 1)
        return (entry >> 16) & 0x7F, (entry & 0xFFFF) / 1000.0

    def on_heartbeat(self, producer: int, now_s: float) -> None:
        """A heartbeat from ``producer`` arrived (monitoring starts with the first one, CiA 301)."""
        if producer == self.consumer()[0]:
            self._last_producer_s = now_s
            self.heartbeat_lost = False  # the heartbeat event is over (its reaction stays until commanded away)

    def _check_heartbeat(self, now_s: float) -> None:
        producer, timeout_s = self.consumer()
        if not producer or timeout_s <= 0.0 or self._last_producer_s is None:
            return
        if now_s - self._last_producer_s <= timeout_s:
            return
        self._last_producer_s = None  # one event per loss; monitoring restarts with the next heartbeat
        self.heartbeat_lost = True
        option = self.limits().abort_option
        log.warning("%s drive: no heartbeat from node %d for %.3f s: 0x6007 = %d", self.name, producer, timeout_s,
                    option)
        if option == 1:
            self.raise_fault(EMCY_HEARTBEAT, ERROR_REGISTER_COMMUNICATION, "heartbeat consumer timeout", now_s)
            return
        self._emcy(EMCY_HEARTBEAT, ERROR_REGISTER_COMMUNICATION)
        if self.state is PowerState.OPERATION_ENABLED and option in (2, 3):
            self.state = PowerState.SWITCH_ON_DISABLED if option == 2 else PowerState.QUICK_STOP_ACTIVE
            self._publish()

    # -- motion ---------------------------------------------------------------------------------------------

    def _stop_rate(self, configured_rpm_s: float) -> float:
        """A deceleration (mill rpm/s): the configured one, else (0: unset) the drive's own maximum."""
        return configured_rpm_s if configured_rpm_s > 0.0 else self.drive.max_accel_rpm_s

    def _profile(self, dt_s: float, now_s: float) -> float:
        """Advance the demand (mill rpm) by ``dt_s`` in the present state; the motor's command."""
        limits = self.limits()
        state = self.state
        if state is PowerState.OPERATION_ENABLED:
            target = 0.0 if self.controlword & power.CW_HALT else min(max(self.target_rpm(), 0.0), limits.max_rpm)
            rate = limits.accel_rpm_s if target > self.demand_rpm else self._stop_rate(limits.decel_rpm_s)
        elif state is PowerState.QUICK_STOP_ACTIVE:
            option = limits.quick_stop_option
            configured = {1: limits.decel_rpm_s, 5: limits.decel_rpm_s, 2: limits.quick_stop_rpm_s,
                          6: limits.quick_stop_rpm_s}.get(option, 0.0)
            target, rate = 0.0, self._stop_rate(configured)
        elif state is PowerState.FAULT_REACTION_ACTIVE:
            target, rate = 0.0, self._stop_rate(limits.quick_stop_rpm_s)
        else:
            self.demand_rpm = 0.0
            return 0.0
        step = rate * dt_s
        self.demand_rpm += min(max(target - self.demand_rpm, -step), step)
        return self.demand_rpm

    @property
    def at_standstill(self) -> bool:
        """No demand, and the sensor and the reference at rest (within the measurement tolerance)."""
        tol = self.tolerance_rpm
        return self.demand_rpm == 0.0 and max(self.model.measured_rpm, self.reference.speed_rpm) <= tol

    def step(self, dt_s: float, now_s: float) -> None:
        """Advance profile and motor by ``dt_s`` (one sub-step), then the automatic transitions."""
        command = self._profile(dt_s, now_s)
        self.model.step(command, dt_s)
        self.reference.step(command, dt_s)

    def supervise(self, dt_s: float, now_s: float) -> None:
        """Once per tick: read the sensor, run the protection and the heartbeat consumer, end stops at rest."""
        measured = self.model.sample()
        faults = self.check.check(measured, self.reference.speed_rpm, dt_s)
        limit_rpm = min(self.value(0x6080) / self.cia.gear_ratio, self.drive.max_speed_rpm)
        self._overspeed = self._overspeed + 1 if measured > limit_rpm + self.tolerance_rpm else 0
        if self._overspeed >= self.check.debounce:
            self.raise_fault(EMCY_OVERSPEED, ERROR_REGISTER_GENERIC, f"{measured:.1f} rpm > {limit_rpm:.1f}", now_s)
        elif FaultFlag.STALL in faults:
            self.raise_fault(EMCY_STALL, ERROR_REGISTER_GENERIC, "the motor does not follow the demand", now_s)
        elif faults:
            self.raise_fault(EMCY_SENSOR, ERROR_REGISTER_GENERIC, "implausible speed sensor", now_s)
        self._check_heartbeat(now_s)
        ends_disabled = self.limits().quick_stop_option in (1, 2, 3, 4)
        if self.state is PowerState.QUICK_STOP_ACTIVE and self.at_standstill and ends_disabled:
            self.state = PowerState.SWITCH_ON_DISABLED  # transition 12
        if self.state is PowerState.FAULT_REACTION_ACTIVE and (
            self.at_standstill or now_s - self._reaction_started_s > self._reaction_bound_s
        ):
            self.state = PowerState.FAULT  # transition 14
        self._publish(measured)

    def _publish(self, measured_rpm: float | None = None) -> None:
        """Write statusword, mode display, demand and actual velocity into the object dictionary."""
        measured = self.model.measured_rpm if measured_rpm is None else measured_rpm
        per_rpm = self._units_per_mill_rpm()
        limits = self.limits()
        extra = 0
        if self.state is PowerState.OPERATION_ENABLED:
            target = max(self.target_rpm(), 0.0)
            if target > limits.max_rpm or self.target_rpm() < 0.0:
                extra |= power.SW_INTERNAL_LIMIT
            if abs(measured - min(target, limits.max_rpm)) <= self.tolerance_rpm:
                extra |= power.SW_TARGET_REACHED
        if measured <= self.tolerance_rpm:
            extra |= power.SW_SPEED_ZERO
        if self.heartbeat_lost:
            extra |= power.SW_WARNING
        self.store(0x6041, 0, power.statusword(self.state, extra=extra))
        self.store(0x6061, 0, self.mode)
        actual = round(measured * per_rpm)
        self.store(0x606C, 0, max(min(actual, 2**31 - 1), -(2**31)))
        self.store(0x606B, 0, round(self.demand_rpm * per_rpm))
        self.store(0x6044, 0, max(min(actual, 2**15 - 1), -(2**15)))
        self.store(0x6043, 0, max(min(round(self.demand_rpm * per_rpm), 2**15 - 1), -(2**15)))

    @property
    def statusword(self) -> int:
        """The statusword now in the object dictionary."""
        return self.value(0x6041)

    def describe(self) -> str:
        """One line: node, state, speeds."""
        return (f"{self.name} drive (node {self.cia.node_id}, {self.cia.mode.value}): {self.state.value}, "
                f"demand {self.demand_rpm:.1f} rpm, motor {self.model.speed_rpm:.1f} rpm")


__all__ = [
    "EMCY_HEARTBEAT",
    "EMCY_OVERSPEED",
    "EMCY_SENSOR",
    "EMCY_STALL",
    "Limits",
    "SimDrive",
]
