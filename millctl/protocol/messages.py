"""Typed messages of the mill bus: one frozen dataclass per frame of ``config/millbus.dbc``.

Each class has the name of its DBC message and one field per signal, with
the same name (units in the names). The E2E signals ``crc`` and ``counter``
are not fields: :class:`millctl.protocol.codec.Codec` fills and checks them.
Enumerations mirror the DBC value tables, so ``cantools decode`` prints the
same names the code uses.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import ClassVar


class CommandCode(enum.IntEnum):
    """A state-machine command from the controller to the node."""

    ARM = 1
    DISARM = 2
    RESET = 3
    STOP = 4
    """Controlled stop (stop category 1): ramp both motors down, heater off."""


class ControllerState(enum.IntEnum):
    """The controller's state, carried in its heartbeat for the node's log."""

    INIT = 0
    IDLE = 1
    ARMED = 2
    RUNNING = 3
    STOPPING = 4
    TRIPPED = 5


class NodeState(enum.IntEnum):
    """The node's state machine (SAFETY.md items 1 and 8)."""

    DISABLED = 0
    ARMED = 1
    RUNNING = 2
    STOPPING = 3
    FAULT = 4


class FaultFlag(enum.IntFlag):
    """Latched node faults, one bit each (``NodeStatus.fault_bits``)."""

    WATCHDOG = 1 << 0
    """No fresh controller heartbeat within the watchdog timeout."""
    E2E_LINK = 1 << 1
    """The net E2E error score of a controller frame reached its limit."""
    ESTOP = 1 << 2
    ENVELOPE = 1 << 3
    """The measured speed pair left the envelope for the debounce count."""
    OVERSPEED = 1 << 4
    STALL = 1 << 5
    SENSOR = 1 << 6
    """A measurement is invalid, stuck or implausible."""
    OVERTEMP = 1 << 7
    HEATER_VERIFY = 1 << 8
    """Heating at full power did not raise the temperature (Klipper's verify_heater)."""
    HEATER_TIMEOUT = 1 << 9
    """The furnace setpoint was not refreshed in time."""
    DRIVE = 1 << 10
    INTERNAL = 1 << 11

    def __repr__(self) -> str:
        """The set bits by name, as an operator reads them in a trip cause: ``WATCHDOG|ESTOP`` (``none``)."""
        return "|".join(str(flag.name) for flag in type(self) if flag & self) or "none"


NO_FAULTS = FaultFlag(0)
"""The empty fault set."""


class FaultCode(enum.IntEnum):
    """One fault as a number (``NodeStatus.first_fault``): code n is ``FaultFlag`` bit n − 1, 0 is none."""

    NONE = 0
    WATCHDOG = 1
    E2E_LINK = 2
    ESTOP = 3
    ENVELOPE = 4
    OVERSPEED = 5
    STALL = 6
    SENSOR = 7
    OVERTEMP = 8
    HEATER_VERIFY = 9
    HEATER_TIMEOUT = 10
    DRIVE = 11
    INTERNAL = 12

    @property
    def flag(self) -> FaultFlag:
        """The matching single-bit :class:`FaultFlag` (empty for ``NONE``)."""
        return NO_FAULTS if self is FaultCode.NONE else FaultFlag(1 << (self.value - 1))

    @classmethod
    def of(cls, flag: FaultFlag) -> FaultCode:
        """The code of a single-bit flag (``NONE`` for the empty flag); several bits are refused."""
        value = int(flag)
        if value == 0:
            return cls.NONE
        if value & (value - 1):
            raise ValueError(f"{flag!r} has several bits set; a fault code names one fault")
        return cls(value.bit_length())


class RefusalCode(enum.IntEnum):
    """Why the node refused the last setpoint frame or command (``NodeStatus.last_refusal``)."""

    NONE = 0
    NOT_ARMED = 1
    FAULT_LATCHED = 2
    ENVELOPE = 3
    SPEED_LIMIT = 4
    ACCEL_LIMIT = 5
    TEMP_LIMIT = 6
    NOT_STANDSTILL = 7
    NOT_FRESH = 8
    """A RESET (or other command) whose counter was not fresh."""
    E2E = 9
    BAD_COMMAND = 10
    WRONG_STATE = 11


class EStopSource(enum.IntEnum):
    """Conventional values of ``EStop.source`` (informational: the node stops for any value)."""

    UNSPECIFIED = 0
    CONTROLLER = 1
    OPERATOR = 2
    BUTTON = 3
    NODE = 4


class SimFaultCode(enum.IntEnum):
    """Faults the simulated node can inject (only with ``--fault-injection``)."""

    CLEAR = 0
    VIB_STALL = 1
    ROTARY_RUNAWAY = 2
    SENSOR_STUCK = 3
    SENSOR_NOISY = 4
    HEATER_FAIL = 5
    NODE_SILENT = 6
    NODE_BABBLE = 7
    TX_LOSS = 8
    TX_CORRUPT = 9


@dataclass(frozen=True)
class EStop:
    """Emergency stop (ID 0x000, highest priority); the node acts on any frame with this ID."""

    source: int = EStopSource.UNSPECIFIED
    E2E: ClassVar[bool] = False


@dataclass(frozen=True)
class Command:
    """A state-machine command, controller → node (event, E2E-protected)."""

    command: CommandCode
    E2E: ClassVar[bool] = True


@dataclass(frozen=True)
class Heartbeat:
    """Controller heartbeat, 20 Hz (E2E-protected; its counter feeds the node's watchdog)."""

    controller_state: ControllerState
    challenge_echo: int = 0
    """The challenge of the latest fresh NodeStatus received (0 … 65535): the node's proof of freshness."""
    E2E: ClassVar[bool] = True


@dataclass(frozen=True)
class Setpoints:
    """Target speeds (rpm) and furnace setpoint (°C), refreshed every 100 ms (E2E-protected)."""

    rotary_rpm: float
    vibration_rpm: float
    furnace_c: float
    heater_on: bool
    E2E: ClassVar[bool] = True


@dataclass(frozen=True)
class NodeStatus:
    """Node state, latched faults and the last refusal, 20 Hz (E2E-protected)."""

    state: NodeState
    fault_bits: FaultFlag = NO_FAULTS
    first_fault: FaultCode = FaultCode.NONE
    refused_setpoints: int = 0
    """Rolling count of refusals, modulo 256."""
    last_refusal: RefusalCode = RefusalCode.NONE
    challenge: int = 0
    """A new number (0 … 65535) each frame, none repeated in 65 536; the heartbeat echoes it (docs/protocol.md)."""
    E2E: ClassVar[bool] = True


@dataclass(frozen=True)
class DriveTelemetry:
    """Measured speeds (rpm) and torques (N·m) of both drives, 50 Hz (E2E-protected)."""

    rotary_rpm: float
    vibration_rpm: float
    rotary_torque_nm: float = 0.0
    vibration_torque_nm: float = 0.0
    E2E: ClassVar[bool] = True


@dataclass(frozen=True)
class FurnaceTelemetry:
    """Furnace temperature and setpoint (°C) and heater duty (%), 10 Hz (E2E-protected)."""

    temp_c: float
    setpoint_c: float
    heater_pct: float
    heater_on: bool
    E2E: ClassVar[bool] = True


@dataclass(frozen=True)
class PhysicsTelemetry:
    """Physics-model telemetry, 10 Hz; informational, so not E2E-protected."""

    detached: bool
    """True when the rods detach from the vial wall, False when pinned."""
    theta_d_deg: float
    """Detachment angle θ_d (degrees)."""
    impact_rate_hz: float
    impact_energy_mj: float
    """Mean impact energy (mJ)."""
    shear_kpa: float
    no_slip_violated: bool = False
    """The paper's no-slip carriage needs more wall friction than μN somewhere (docs/model.md, slip)."""
    E2E: ClassVar[bool] = False


@dataclass(frozen=True)
class SimFault:
    """Fault injection for the simulated node (0x700–0x7FF are reserved for simulator control)."""

    fault: SimFaultCode
    active: bool = True
    param: float = 0.0
    """Unit depends on the fault: rpm, °C, a probability 0–1 or Hz (see docs/protocol.md)."""
    E2E: ClassVar[bool] = False


MillMessage = (
    EStop
    | Command
    | Heartbeat
    | Setpoints
    | NodeStatus
    | DriveTelemetry
    | FurnaceTelemetry
    | PhysicsTelemetry
    | SimFault
)
"""Any message of the mill bus."""

MESSAGE_TYPES: tuple[type[MillMessage], ...] = (
    EStop,
    Command,
    Heartbeat,
    Setpoints,
    NodeStatus,
    DriveTelemetry,
    FurnaceTelemetry,
    PhysicsTelemetry,
    SimFault,
)
"""Every message class, in identifier order; each is named after its DBC message."""

ESTOP_ID = 0x000
"""Identifier of the E-stop frame: the node stops for any frame with it, before decoding."""

SIM_CONTROL_IDS = range(0x700, 0x800)
"""Identifiers reserved for simulator control (fault injection)."""


__all__ = [
    "ESTOP_ID",
    "MESSAGE_TYPES",
    "NO_FAULTS",
    "SIM_CONTROL_IDS",
    "Command",
    "CommandCode",
    "ControllerState",
    "DriveTelemetry",
    "EStop",
    "EStopSource",
    "FaultCode",
    "FaultFlag",
    "FurnaceTelemetry",
    "Heartbeat",
    "MillMessage",
    "NodeState",
    "NodeStatus",
    "PhysicsTelemetry",
    "RefusalCode",
    "Setpoints",
    "SimFault",
    "SimFaultCode",
]
