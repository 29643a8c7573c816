"""The mill bus protocol: the DBC codec, E2E protection, the bus factory and bus logging.

``config/millbus.dbc`` is the one source of truth for the wire; this package
is the only code that packs bytes (:class:`Codec`) or knows python-can
interfaces (:func:`open_bus`). See docs/protocol.md.
"""

from __future__ import annotations

from millctl.protocol.busload import BusLoad, bus_load
from millctl.protocol.buslog import RotatingBusLog
from millctl.protocol.codec import DBC_NAME, Codec, Decoded, default_codec
from millctl.protocol.e2e import AliveCounter, E2EReceiver, E2EStatus, crc8_sae_j1850, e2e_crc, sequence_decay_s
from millctl.protocol.errors import ProtocolError, SignalRangeError
from millctl.protocol.factory import bus_kwargs, estop_channel_kwargs, open_bus, open_estop_channel
from millctl.protocol.messages import (
    ESTOP_ID,
    MESSAGE_TYPES,
    NO_FAULTS,
    SIM_CONTROL_IDS,
    Command,
    CommandCode,
    ControllerState,
    DriveTelemetry,
    EStop,
    EStopSource,
    FaultCode,
    FaultFlag,
    FurnaceTelemetry,
    Heartbeat,
    MillMessage,
    NodeState,
    NodeStatus,
    PhysicsTelemetry,
    RefusalCode,
    Setpoints,
    SimFault,
    SimFaultCode,
)
from millctl.protocol.receive import Batch, BusReader, ReceiveCounts, is_estop

__all__ = [
    "DBC_NAME",
    "ESTOP_ID",
    "MESSAGE_TYPES",
    "NO_FAULTS",
    "SIM_CONTROL_IDS",
    "AliveCounter",
    "Batch",
    "BusLoad",
    "BusReader",
    "Codec",
    "Command",
    "CommandCode",
    "ControllerState",
    "Decoded",
    "DriveTelemetry",
    "E2EReceiver",
    "E2EStatus",
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
    "ProtocolError",
    "ReceiveCounts",
    "RefusalCode",
    "RotatingBusLog",
    "Setpoints",
    "SignalRangeError",
    "SimFault",
    "SimFaultCode",
    "bus_kwargs",
    "bus_load",
    "crc8_sae_j1850",
    "default_codec",
    "e2e_crc",
    "estop_channel_kwargs",
    "is_estop",
    "open_bus",
    "open_estop_channel",
    "sequence_decay_s",
]
