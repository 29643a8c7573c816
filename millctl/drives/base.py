"""The drives boundary: what the controller needs from "the drives", and the only thing the backends share.

The controller speaks to the mill's drives only through :class:`DrivesBackend`:
it drains their observations each tick (the node-shaped reports it judges:
:class:`~millctl.protocol.NodeStatus`, :class:`~millctl.protocol.DriveTelemetry`,
:class:`~millctl.protocol.FurnaceTelemetry`), commands them
(:class:`~millctl.protocol.CommandCode`: arm, disarm, controlled stop, fault
reset), sends the checked speed pair, quick-stops them (E-stop), keeps them
alive (heartbeat) and asks them to take a move's limits before it starts (the
second channel, SAFETY 28). In the manner of python-can's ``BusABC``, the public
methods own the invariants — a send that fails is logged and never raised into
the control loop; a drain never raises for what the bus delivers — and each
backend fills small ``_hooks``. Backends: :mod:`millctl.drives.millbus` (the
millbus node, ``config/millbus.dbc``) and :mod:`millctl.drives.cia402`
(standard CANopen CiA 402 drives).
"""

from __future__ import annotations

import abc
import enum
import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import can

from millctl.errors import InterlockError
from millctl.protocol import BusReader, CommandCode, Decoded, EStopSource, ReceiveCounts
from millctl.protocol import ControllerState as WireState
from millctl.safety import SpeedPoint, Trajectory

log = logging.getLogger(__name__)


class LimitsState(enum.StrEnum):
    """Where a move's drive-side limits stand (:meth:`DrivesBackend.limits_state`)."""

    READY = "ready"
    """Written and read back (or the backend keeps its limits elsewhere): the move may start."""
    PENDING = "pending"
    """Being written and read back: the move waits."""
    REFUSED = "refused"
    """A read-back differed or a transfer failed: the move is refused (:attr:`DrivesBackend.limits_error`)."""


class DriveLimitsRefused(InterlockError):
    """A drive did not take the limits written to it: it is not enabled and the move is refused."""


@dataclass(frozen=True)
class DriveInfo:
    """One drive as the operator sees it: name, state in the backend's words, and what is wrong (or "")."""

    name: str
    state: str
    node_id: int | None = None
    detail: str = ""


@dataclass(frozen=True)
class DrivesBatch:
    """One drain: the node-shaped reports in arrival order, and the CAN error frames seen."""

    decoded: list[Decoded] = field(default_factory=list)
    error_frames: list[can.Message] = field(default_factory=list)


class DrivesBackend(abc.ABC):
    """The mill's drives as the controller needs them (template methods; backends fill the hooks)."""

    backend: str = ""
    """The backend's name as the configuration spells it (``[drives] backend``)."""
    e2e: bool = True
    """Whether the reports carry an E2E counter and CRC the controller checks (millbus yes, CANopen no)."""
    has_furnace: bool = True
    """Whether furnace telemetry is expected (a CiA 402 mill milling cold has none)."""

    def __init__(self, bus: can.BusABC) -> None:
        self.bus = bus
        self.reader = BusReader(bus, "controller")
        """Both backends drain the bus once per tick through it, counting bad input (SAFETY 19, 22)."""

    # -- what the controller reads
    @property
    def counts(self) -> ReceiveCounts:
        """Everything the backend's bus reader has counted (frames, bad input, errors)."""
        return self.reader.counts

    def drain(self, now_s: float) -> DrivesBatch:
        """Every report waiting, in arrival order; never raises for anything the bus delivers (SAFETY 19)."""
        return self._drain(now_s)

    @abc.abstractmethod
    def _drain(self, now_s: float) -> DrivesBatch: ...

    def describe(self) -> list[DriveInfo]:
        """Each drive's state in the backend's own words (status, TUI, ``millctl bus check``)."""
        return self._describe()

    @abc.abstractmethod
    def _describe(self) -> list[DriveInfo]: ...

    def fault_detail(self) -> str:
        """The first cause of the drives' fault in words ("" when the report's fault code says it all)."""
        return ""

    # -- what the controller sends
    def command(self, code: CommandCode) -> None:
        """Send a state-machine command (the controller awaits its confirmation in the reports)."""
        self._guarded(f"command {code.name}", lambda: self._command(code))

    def estop(self, source: EStopSource) -> None:
        """Quick-stop every drive (repeated by the controller until the reports show it)."""
        self._guarded("E-stop", lambda: self._estop(source))

    def heartbeat(self, state: WireState, challenge: int) -> None:
        """The controller's heartbeat (its absence stops the drives by their own means)."""
        self._guarded("heartbeat", lambda: self._heartbeat(state, challenge))

    def setpoints(self, speeds: SpeedPoint, furnace_c: float, heater_on: bool) -> None:
        """The snapped speed pair the interlock checked (rpm), and the furnace setpoint (°C)."""
        self._guarded("setpoints", lambda: self._setpoints(speeds, furnace_c, heater_on))

    def periodic(self, now_s: float) -> None:
        """The backend's own duty each tick (CiA 402: the RPDO refresh and the power-state steps)."""
        self._guarded("periodic duty", lambda: self._periodic(now_s))

    @abc.abstractmethod
    def _command(self, code: CommandCode) -> None: ...

    @abc.abstractmethod
    def _estop(self, source: EStopSource) -> None: ...

    @abc.abstractmethod
    def _heartbeat(self, state: WireState, challenge: int) -> None: ...

    @abc.abstractmethod
    def _setpoints(self, speeds: SpeedPoint, furnace_c: float, heater_on: bool) -> None: ...

    @abc.abstractmethod
    def _periodic(self, now_s: float) -> None: ...

    def _guarded(self, what: str, send: Callable[[], None]) -> None:
        try:
            send()
        except can.CanError as exc:
            log.warning("bus send failed for %s: %s", what, exc)

    # -- the second channel (SAFETY 28)
    def prepare_move(self, move: Trajectory | None) -> None:
        """Start giving the drives a move's limits (None: the limits for arming at standstill)."""
        self._prepare_move(move)

    @abc.abstractmethod
    def _prepare_move(self, move: Trajectory | None) -> None: ...

    def limits_state(self) -> LimitsState:
        """Whether the limits of the last :meth:`prepare_move` are in force."""
        return LimitsState.READY

    @property
    def limits_error(self) -> str:
        """Why the last limits were refused ("" unless :meth:`limits_state` is REFUSED)."""
        return ""

    @abc.abstractmethod
    def close(self) -> None:
        """Let go of anything the backend started (threads, subscriptions); the bus is the caller's."""


__all__ = ["DriveInfo", "DriveLimitsRefused", "DrivesBackend", "DrivesBatch", "LimitsState"]
