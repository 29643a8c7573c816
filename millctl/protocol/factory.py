"""The bus factory: the one place that turns the validated ``[bus]`` config into a ``can.BusABC``.

Nothing else in millctl names a python-can interface. ``udp_multicast`` and
``millctl_udp_multicast`` both open :class:`~millctl.protocol.udp.EchoFreeUdpMulticastBus`
(no self-echo, TTL 0 enforced), because the stock interface hands a sender
its own frames back, which no real CAN bus does.
"""

from __future__ import annotations

import logging
from typing import Any

import can

from millctl.config.models import Bus
from millctl.errors import BusError

log = logging.getLogger(__name__)

_PYTHON_CAN_NAME = {
    "virtual": "virtual",
    "socketcan": "socketcan",
    "udp_multicast": "millctl_udp_multicast",
    "millctl_udp_multicast": "millctl_udp_multicast",
}


def bus_kwargs(bus_config: Bus) -> dict[str, Any]:
    """The keyword arguments of ``can.Bus`` for a bus config (classic CAN, never our own echo)."""
    interface = _PYTHON_CAN_NAME[bus_config.interface]
    kwargs: dict[str, Any] = {"interface": interface, "channel": bus_config.channel}
    if interface == "virtual":
        kwargs["receive_own_messages"] = False
    elif interface == "socketcan":
        # The bitrate of a SocketCAN device is set on the link (`ip link set can0 type can bitrate …`).
        kwargs["fd"] = False
        kwargs["receive_own_messages"] = False
    else:
        kwargs["fd"] = False
    kwargs.update(bus_config.options)
    return kwargs


def open_bus(bus_config: Bus) -> can.BusABC:
    """Open the configured CAN bus; any failure is a :class:`~millctl.errors.BusError` naming the bus."""
    kwargs = bus_kwargs(bus_config)
    try:
        bus = can.Bus(**kwargs)
    except (can.CanError, OSError, ValueError, TypeError) as exc:
        raise BusError(
            f"cannot open the CAN bus (interface {bus_config.interface}, channel {bus_config.channel!r}, "
            f"options {bus_config.options}): {exc}"
        ) from exc
    log.info("opened CAN bus %s", bus.channel_info)
    return bus


__all__ = ["bus_kwargs", "open_bus"]
