"""The millbus backend: the drives and the furnace behind one custom node that speaks ``config/millbus.dbc``.

Today's behaviour, moved behind :class:`~millctl.drives.base.DrivesBackend`:
every frame carries the DBC's E2E counter and CRC, the node checks every
setpoint against its own copy of the envelope (the second channel), and the
E-stop is the highest-priority frame (docs/protocol.md).
"""

from __future__ import annotations

import can

from millctl.drives.base import DriveInfo, DrivesBackend, DrivesBatch
from millctl.protocol import (
    AliveCounter,
    Codec,
    Command,
    CommandCode,
    EStop,
    EStopSource,
    Heartbeat,
    MillMessage,
    ProtocolError,
    Setpoints,
    default_codec,
)
from millctl.protocol import ControllerState as WireState
from millctl.safety import SpeedPoint, Trajectory


class MillbusDrives(DrivesBackend):
    """The millbus node on one bus: frames encoded and decoded with the DBC, alive counters per kind."""

    backend = "millbus"
    e2e = True
    has_furnace = True

    def __init__(self, bus: can.BusABC, codec: Codec | None = None) -> None:
        super().__init__(bus)
        self.codec = codec or default_codec()
        self.counters: dict[type[MillMessage], AliveCounter] = {
            kind: AliveCounter() for kind in (Heartbeat, Setpoints, Command)
        }

    def send(self, message: MillMessage) -> None:
        """Encode one message with its kind's next alive counter and send it (a failed send is logged)."""
        self._guarded(type(message).__name__, lambda: self._send(message))

    def _send(self, message: MillMessage) -> None:
        counter = self.counters[type(message)].next() if type(message) in self.counters else 0
        self.bus.send(self.codec.encode(message, counter))

    def _drain(self, now_s: float) -> DrivesBatch:
        batch = self.reader.drain()
        decoded = []
        for frame in batch.frames:
            try:
                decoded.append(self.codec.decode(frame))
            except ProtocolError as exc:
                self.reader.malformed(frame, exc)
        return DrivesBatch(decoded, batch.error_frames)

    def _describe(self) -> list[DriveInfo]:
        return []  # the drives are the node's: its state is the status's node_state

    def _periodic(self, now_s: float) -> None:
        """No duty of its own: heartbeat and setpoints are sent when the controller says."""

    def _prepare_move(self, move: Trajectory | None) -> None:
        """Nothing to write: the node checks every setpoint against its own envelope (the second channel)."""

    def close(self) -> None:
        """Nothing started: the bus is the caller's."""

    def _command(self, code: CommandCode) -> None:
        self._send(Command(code))

    def _estop(self, source: EStopSource) -> None:
        self._send(EStop(source))

    def _heartbeat(self, state: WireState, challenge: int) -> None:
        self._send(Heartbeat(state, challenge))

    def _setpoints(self, speeds: SpeedPoint, furnace_c: float, heater_on: bool) -> None:
        self._send(
            Setpoints(
                rotary_rpm=speeds.omega_r_rpm,
                vibration_rpm=speeds.omega_v_rpm,
                furnace_c=furnace_c,
                heater_on=heater_on,
            )
        )


__all__ = ["MillbusDrives"]
