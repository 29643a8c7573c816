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

from millctl.config.bus import DOCS, FD_DATA_BITRATE_KWARG, NUMBERED_CHANNEL, Bus, python_can_page
from millctl.errors import BusError

log = logging.getLogger(__name__)

_PYTHON_CAN_NAME = {"udp_multicast": "millctl_udp_multicast"}
"""The stock udp_multicast echoes a sender's own frames: it opens the echo-free one (millctl.protocol.udp)."""

_NO_BITRATE = frozenset({"socketcan", "virtual", "millctl_udp_multicast", "socketcand"})
"""Interfaces whose driver sets no bitrate (socketcan: the link's, `ip link set … bitrate`; the rest: none)."""


def _channel(interface: str, channel: str) -> str | int | list[int]:
    """The channel as the driver wants it: a number for the numbered adapters, a list for vector's "0, 1"."""
    if interface in NUMBERED_CHANNEL:
        return int(channel)
    if interface == "vector":
        numbers = [int(part) for part in channel.split(",")]
        return numbers[0] if len(numbers) == 1 else numbers
    return channel


def bus_kwargs(bus_config: Bus) -> dict[str, Any]:
    """The keyword arguments of ``can.Bus`` for a bus config (never our own echo; error frames on)."""
    interface = _PYTHON_CAN_NAME.get(bus_config.interface, bus_config.interface)
    kwargs: dict[str, Any] = {"interface": interface, "channel": _channel(interface, bus_config.channel)}
    kwargs["receive_own_messages"] = False
    if interface not in _NO_BITRATE:
        kwargs["bitrate"] = bus_config.bitrate_bit_s
    if interface == "socketcan":
        # python-can sets CAN_RAW_ERR_FILTER to every error class unless told to ignore them: error frames,
        # error-passive and bus-off reach the controller (millctl.protocol.bus_health).
        kwargs["ignore_rx_error_frames"] = False
    if interface != "virtual":
        kwargs["fd"] = bus_config.fd
    if bus_config.fd and bus_config.data_bitrate_bit_s is not None and interface in FD_DATA_BITRATE_KWARG:
        kwargs["data_bitrate"] = bus_config.data_bitrate_bit_s
    kwargs.update(bus_config.options)
    return kwargs


def open_bus(bus_config: Bus) -> can.BusABC:
    """Open the configured CAN bus; any failure is a :class:`~millctl.errors.BusError` naming the bus."""
    kwargs = bus_kwargs(bus_config)
    try:
        bus = can.Bus(**kwargs)
    except (can.CanError, OSError, ValueError, TypeError, ImportError) as exc:
        driver = ""
        if isinstance(exc, (can.CanInterfaceNotImplementedError, ImportError)):
            driver = (
                f"; the driver of {bus_config.interface} is missing: install the vendor library, and for slcan or "
                "gs_usb the extra millctl[adapters] (pyserial, pyusb)"
            )
        raise BusError(
            f"cannot open the CAN bus (interface {bus_config.interface}, channel {bus_config.channel!r}, "
            f"options {bus_config.options}): {exc}{driver} ({DOCS}; {python_can_page(bus_config.interface)})"
        ) from exc
    log.info("opened CAN bus %s", bus.channel_info)
    return bus


__all__ = ["bus_kwargs", "open_bus"]
