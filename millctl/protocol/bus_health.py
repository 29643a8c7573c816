"""The CAN controller's own health: error frames, error-passive and bus-off, seen, counted and told apart.

A CAN controller counts its transmit and receive errors (TEC, REC; ISO
11898-1): at 96 it warns, at 128 it goes **error-passive** (it may no longer
signal errors actively), at 256 transmit errors it goes **bus-off** and takes
no part in the bus at all: the heartbeat stops, and the node's watchdog stops
the mill. millctl sees this two ways (docs/protocol.md#bus-errors):

- **Error frames** (``can.Message.is_error_frame``). SocketCAN delivers them
  when the socket's error mask (``CAN_RAW_ERR_FILTER``) asks for them, which
  python-can's socketcan driver sets to every class unless
  ``ignore_rx_error_frames`` is given (the config refuses that option). Their
  layout is ``linux/can/error.h``: the class bits in the identifier
  (``CAN_ERR_BUSOFF`` 0x40, ``CAN_ERR_CRTL`` 0x04 with the warning/passive
  bits in ``data[1]``, ``CAN_ERR_ACK`` 0x20, …) and TEC/REC in ``data[6]``,
  ``data[7]``. The virtual and multicast test buses carry the same layout.
  Other drivers' error frames (pcan, kvaser, vector) are counted, unclassified.
- **The adapter's state**, polled: ``bus.state`` (``can.BusState``) where the
  driver reports the controller's live state (ixxat, etas; ``ERROR`` is bus-off,
  ``PASSIVE`` error-passive), and PCAN's ``status()`` (``PCAN_ERROR_BUSOFF``,
  ``PCAN_ERROR_BUSPASSIVE``, ``PCAN_ERROR_BUSWARNING``). pcan's and systec's
  ``state`` is a listen-only switch, not a condition, and is never read.

:class:`BusHealthMonitor` keeps the counts and the condition; the controller
trips on bus-off naming its cause (docs/safety.md).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import can

from millctl.api.enums import BusCondition

CAN_ERR_TX_TIMEOUT = 0x001
CAN_ERR_LOSTARB = 0x002
CAN_ERR_CRTL = 0x004
CAN_ERR_PROT = 0x008
CAN_ERR_TRX = 0x010
CAN_ERR_ACK = 0x020
CAN_ERR_BUSOFF = 0x040
CAN_ERR_BUSERROR = 0x080
CAN_ERR_RESTARTED = 0x100
CAN_ERR_CNT = 0x200
"""Error classes in an error frame's identifier (linux/can/error.h)."""
CAN_ERR_CRTL_WARNING = 0x04 | 0x08
"""``data[1]``: RX or TX error counter reached the warning level (96)."""
CAN_ERR_CRTL_PASSIVE = 0x10 | 0x20
"""``data[1]``: RX or TX error counter reached error-passive (128)."""
CAN_ERR_CRTL_ACTIVE = 0x40
"""``data[1]``: recovered to error-active."""

_CLASS_NAMES = (
    (CAN_ERR_TX_TIMEOUT, "TX timeout"),
    (CAN_ERR_LOSTARB, "lost arbitration"),
    (CAN_ERR_CRTL, "controller problem"),
    (CAN_ERR_PROT, "protocol violation"),
    (CAN_ERR_TRX, "transceiver"),
    (CAN_ERR_ACK, "no ACK"),
    (CAN_ERR_BUSOFF, "bus-off"),
    (CAN_ERR_BUSERROR, "bus error"),
    (CAN_ERR_RESTARTED, "restarted"),
)
_COUNTED = (
    (CAN_ERR_TX_TIMEOUT, "tx_timeouts"),
    (CAN_ERR_LOSTARB, "arbitration_lost"),
    (CAN_ERR_CRTL, "controller_errors"),
    (CAN_ERR_PROT | CAN_ERR_BUSERROR, "bus_errors"),
    (CAN_ERR_ACK, "ack_errors"),
    (CAN_ERR_RESTARTED, "restarts"),
)
"""Which :class:`BusHealth` count each error class adds to (a frame with PROT and BUSERROR is one bus error)."""

SOCKETCAN_LAYOUT = frozenset({"socketcan", "virtual", "udp_multicast", "millctl_udp_multicast"})
"""Interfaces whose error frames follow linux/can/error.h."""
STATE_IS_A_MODE = frozenset({"pcan", "systec"})
"""Drivers whose ``state`` property is the listen-only switch, not the controller's condition."""


@dataclass
class BusHealth:
    """What the controller's CAN adapter has reported since start."""

    interface: str
    condition: BusCondition = BusCondition.ERROR_ACTIVE
    state_source: str = "error frames"
    """How the condition is known: error frames, and the adapter's state where its driver reports one."""
    error_frames: int = 0
    bus_errors: int = 0
    """Protocol violations and bus errors (bit, stuff, form, CRC errors)."""
    ack_errors: int = 0
    """Frames nobody acknowledged: no other node on the bus, or a wrong bitrate."""
    arbitration_lost: int = 0
    controller_errors: int = 0
    """Controller problems: buffer overflows, warning and passive levels."""
    tx_timeouts: int = 0
    error_passive_count: int = 0
    """Times the controller went error-passive."""
    bus_off_count: int = 0
    """Times the controller went bus-off."""
    restarts: int = 0
    """Times the controller restarted after bus-off (``ip link … restart-ms``)."""
    tx_error_counter: int | None = None
    """TEC in the latest error frame that carried it (None: not reported)."""
    rx_error_counter: int | None = None
    last_error: str = ""

    def as_dict(self) -> dict[str, int | str | None]:
        """As plain data (for the status)."""
        data = asdict(self)
        data["condition"] = self.condition.value
        return data


def adapter_of(bus: can.BusABC) -> can.BusABC:
    """The adapter's own bus under wrappers that keep it as ``inner`` (:class:`millctl.service.tap.TappedBus`)."""
    seen = 0
    while isinstance(getattr(bus, "inner", None), can.BusABC) and seen < 8:
        bus = bus.inner  # type: ignore[attr-defined]
        seen += 1
    return bus


def _reports_state(adapter: can.BusABC, interface: str) -> bool:
    return interface not in STATE_IS_A_MODE and type(adapter).state is not can.BusABC.state


def _pcan_condition(adapter: can.BusABC) -> BusCondition | None:
    from can.interfaces.pcan.basic import PCAN_ERROR_BUSOFF, PCAN_ERROR_BUSPASSIVE, PCAN_ERROR_BUSWARNING

    status = int(adapter.status())  # type: ignore[attr-defined]
    if status & PCAN_ERROR_BUSOFF:
        return BusCondition.BUS_OFF
    if status & PCAN_ERROR_BUSPASSIVE:
        return BusCondition.ERROR_PASSIVE
    if status & PCAN_ERROR_BUSWARNING:
        return BusCondition.ERROR_WARNING
    return BusCondition.ERROR_ACTIVE


_STATE_CONDITION = {
    can.BusState.ACTIVE: BusCondition.ERROR_ACTIVE,
    can.BusState.PASSIVE: BusCondition.ERROR_PASSIVE,
    can.BusState.ERROR: BusCondition.BUS_OFF,
}


class BusHealthMonitor:
    """Counts error frames and polls the adapter's state; reports each change of condition once."""

    def __init__(self, bus: can.BusABC, interface: str) -> None:
        self.adapter = adapter_of(bus)
        self.interface = interface
        self.health = BusHealth(interface)
        self._pcan = interface == "pcan" and hasattr(self.adapter, "status")
        self._state = _reports_state(self.adapter, interface)
        if self._pcan:
            self.health.state_source = "error frames and PCAN status()"
        elif self._state:
            self.health.state_source = "error frames and the adapter's bus.state"

    def on_error_frame(self, frame: can.Message) -> BusCondition | None:
        """Count an error frame; the new condition if it changed the condition, else None."""
        health = self.health
        health.error_frames += 1
        if self.interface not in SOCKETCAN_LAYOUT:
            health.last_error = f"error frame 0x{frame.arbitration_id:X} data {bytes(frame.data).hex()}"
            return None
        cls, data = frame.arbitration_id, bytes(frame.data).ljust(8, b"\0")
        names = [name for bit, name in _CLASS_NAMES if cls & bit]
        for bits, count in _COUNTED:
            if cls & bits:
                setattr(health, count, getattr(health, count) + 1)
        if cls & (CAN_ERR_CNT | CAN_ERR_CRTL):
            health.tx_error_counter, health.rx_error_counter = data[6], data[7]
        counters = "" if health.tx_error_counter is None else (
            f", TEC {health.tx_error_counter} REC {health.rx_error_counter}"
        )
        health.last_error = f"error frame: {', '.join(names) or 'unclassified'} (class 0x{cls:03X}{counters})"
        if cls & CAN_ERR_BUSOFF:
            return self._become(BusCondition.BUS_OFF)
        if cls & CAN_ERR_RESTARTED or (cls & CAN_ERR_CRTL and data[1] & CAN_ERR_CRTL_ACTIVE):
            return self._become(BusCondition.ERROR_ACTIVE)
        if cls & CAN_ERR_CRTL and data[1] & CAN_ERR_CRTL_PASSIVE:
            return self._become(BusCondition.ERROR_PASSIVE)
        if cls & CAN_ERR_CRTL and data[1] & CAN_ERR_CRTL_WARNING:
            return self._become(BusCondition.ERROR_WARNING)
        return None

    def poll(self) -> BusCondition | None:
        """Read the adapter's state where its driver reports one; the new condition if it changed, else None."""
        try:
            if self._pcan:
                condition = _pcan_condition(self.adapter)
            elif self._state:
                condition = _STATE_CONDITION.get(self.adapter.state)
            else:
                return None
        except (can.CanError, OSError, ValueError) as exc:
            self.health.last_error = f"reading the adapter's state failed: {type(exc).__name__}: {exc}"
            return None
        return None if condition is None else self._become(condition)

    def _become(self, condition: BusCondition) -> BusCondition | None:
        health = self.health
        if condition is health.condition:
            return None
        health.condition = condition
        if condition is BusCondition.BUS_OFF:
            health.bus_off_count += 1
        elif condition is BusCondition.ERROR_PASSIVE:
            health.error_passive_count += 1
        return condition


__all__ = [
    "SOCKETCAN_LAYOUT",
    "BusCondition",
    "BusHealth",
    "BusHealthMonitor",
    "adapter_of",
]
