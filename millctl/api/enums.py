"""The enumerations of the service contract, defined once: controller and run states, event and error kinds.

Every one is a :class:`enum.StrEnum`, so its members compare equal to the
strings on the wire and serialise as those strings; callers compare members
(``status.state is ControllerState.TRIPPED``), never hand-typed strings.
"""

from __future__ import annotations

import enum


class ControllerState(enum.StrEnum):
    """States of the controller (docs/safety.md#state-machine)."""

    DISCONNECTED = "DISCONNECTED"
    """No node seen yet (or the node was lost)."""
    DISABLED = "DISABLED"
    """Node present, drives disabled: arm to go on."""
    ARMED = "ARMED"
    """Drives enabled at standstill: a setpoint starts them."""
    RUNNING = "RUNNING"
    """Drives running at (or ramping to) their setpoints."""
    STOPPING = "STOPPING"
    """Controlled stop: both drives ramp down inside the envelope."""
    TRIPPED = "TRIPPED"
    """A trip latched: only reset (at standstill) leaves it."""


class BusCondition(enum.StrEnum):
    """The CAN controller's fault-confinement state (ISO 11898-1)."""

    ERROR_ACTIVE = "error-active"
    """Normal: error counters below 96."""
    ERROR_WARNING = "error-warning"
    """An error counter reached 96: errors are frequent."""
    ERROR_PASSIVE = "error-passive"
    """An error counter reached 128: the controller no longer signals errors actively."""
    BUS_OFF = "bus-off"
    """Transmit error counter past 255: the controller takes no part in the bus."""


class RunState(enum.StrEnum):
    """Where a recipe run is (docs/operations.md#recipes)."""

    STARTING = "STARTING"
    RUNNING = "RUNNING"
    PAUSED = "PAUSED"
    HELD = "HELD"
    """Held automatically (furnace out of its band); the operator resumes."""
    STOPPING = "STOPPING"
    DONE = "DONE"
    ABORTED = "ABORTED"
    FAILED = "FAILED"
    INTERRUPTED = "INTERRUPTED"
    """The service stopped (or died) under the run: it is unfinished, and ``millctl recipe resume RUN`` continues it
    (docs/operations.md#resume)."""

    @property
    def final(self) -> bool:
        """True once the run has ended (DONE, ABORTED or FAILED)."""
        return self in (RunState.DONE, RunState.ABORTED, RunState.FAILED)

    @property
    def resumable(self) -> bool:
        """True when ``resume`` applies (PAUSED or HELD)."""
        return self in (RunState.PAUSED, RunState.HELD)


class EventKind(enum.StrEnum):
    """What an event records."""

    STATE = "state"
    """A state change of the controller."""
    COMMAND = "command"
    """A command was accepted."""
    REFUSAL = "refusal"
    """A command was refused (by the interlock or the state)."""
    TRIP = "trip"
    """A trip latched."""
    NODE = "node"
    """Something the node reported."""
    CONFIG = "config"
    """The configuration in force."""
    CONTROL = "control"
    """The control lease was taken or released."""
    SERVICE = "service"
    """The service started, stopped or failed."""
    RECORDS = "records"
    """Records could not be written (a full or failing disk), or can be again."""
    BUS = "bus"
    """The CAN controller's condition changed: error-warning, error-passive, bus-off, back to error-active."""
    DRILL = "drill"
    """An instructor injected or cleared a simulated node fault (``millctl serve --fault-injection``)."""
    HOST = "host"
    """The host: the control loop ran late, no real-time policy, or a trip the host caused (SAFETY 27)."""


class SimFaultName(enum.StrEnum):
    """The simulated node's injectable faults (``firmware_sim/faults.py``; docs/operations.md#fault-injection).

    The names of :class:`millctl.protocol.messages.SimFaultCode`, on the wire of the API as strings.
    """

    CLEAR = "CLEAR"
    """Clear every injected fault (latched node faults stay until a reset)."""
    VIB_STALL = "VIB_STALL"
    ROTARY_RUNAWAY = "ROTARY_RUNAWAY"
    SENSOR_STUCK = "SENSOR_STUCK"
    SENSOR_NOISY = "SENSOR_NOISY"
    HEATER_FAIL = "HEATER_FAIL"
    NODE_SILENT = "NODE_SILENT"
    NODE_BABBLE = "NODE_BABBLE"
    TX_LOSS = "TX_LOSS"
    TX_CORRUPT = "TX_CORRUPT"


class ErrorCode(enum.StrEnum):
    """The stable code of every API error (docs/operations.md#errors)."""

    INTERLOCK_REFUSED = "interlock_refused"
    RECIPE_REFUSED = "recipe_refused"
    WRONG_STATE = "wrong_state"
    INVALID_REQUEST = "invalid_request"
    INVALID_INPUT = "invalid_input"
    CONTROL_HELD = "control_held"
    UNAUTHORIZED = "unauthorized"
    NODE_UNREACHABLE = "node_unreachable"
    BUSY = "busy"
    BODY_TOO_LARGE = "body_too_large"
    BAD_REQUEST = "bad_request"
    RUN_NOT_FOUND = "run_not_found"
    HTTP_ERROR = "http_error"


class StreamKind(enum.StrEnum):
    """The kinds of server-sent event on ``GET /v1/stream``."""

    STATUS = "status"
    """A :class:`~millctl.api.models.StatusOut`, every 0.25 s."""
    EVENT = "event"
    """An :class:`~millctl.api.models.EventOut`, as it happens (its ``id`` is its sequence number)."""


__all__ = ["BusCondition", "ControllerState", "ErrorCode", "EventKind", "RunState", "StreamKind"]
