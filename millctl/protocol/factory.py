"""The bus factory: the one place that turns the validated ``[bus]`` config into a ``can.BusABC``.

Nothing else in millctl names a python-can interface. ``udp_multicast`` and
``millctl_udp_multicast`` both open :class:`~millctl.protocol.udp.EchoFreeUdpMulticastBus`
(no self-echo, TTL 0 enforced), because the stock interface hands a sender
its own frames back, which no real CAN bus does.

:func:`open_estop_channel` opens a second receive channel that carries only the
E-stop identifier, where the interface filters in the kernel (SocketCAN): the
equivalent of a CAN controller's dedicated receive mailbox, so that no flood on
other identifiers can fill the queue an E-stop has to reach a loop through.
"""

from __future__ import annotations

import logging
import socket
from typing import Any

import can

from millctl.config.bus import DOCS, FD_DATA_BITRATE_KWARG, NUMBERED_CHANNEL, Bus, python_can_page
from millctl.errors import BusError
from millctl.protocol.drivers import install_hint
from millctl.protocol.messages import ESTOP_ID

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
    """Open the configured CAN bus; any failure is a :class:`~millctl.errors.BusError` naming the bus.

    Any exception of the driver counts (python-can's kvaser raises ``NameError`` when CANlib is missing):
    the error says what the interface needs installed (:func:`~millctl.protocol.drivers.install_hint`).
    """
    kwargs = bus_kwargs(bus_config)
    try:
        if kwargs["interface"] == "socketcand":
            _reach_socketcand(kwargs)
        bus = can.Bus(**kwargs)
    except Exception as exc:  # a vendor driver may raise anything: each is "cannot open"
        raise BusError(_cannot_open(bus_config, exc)) from exc
    log.info("opened CAN bus %s", bus.channel_info)
    return bus


SOCKETCAND_CONNECT_S = 2.0
"""How long a socketcand daemon has to accept the connection (s) before the bus is refused."""


def _reach_socketcand(kwargs: dict[str, Any]) -> None:
    """Refuse at once a socketcand daemon that does not accept a connection (raises OSError).

    python-can's socketcand interface retries a refused connection in a busy
    loop for 10 s, logging a warning at every attempt; one attempt with a
    timeout says the same in one line.
    """
    host, port = kwargs.get("host"), kwargs.get("port")
    if not isinstance(host, str) or not isinstance(port, int):
        return  # python-can names what is missing
    with socket.create_connection((host, port), timeout=SOCKETCAND_CONNECT_S):
        pass


def _cannot_open(bus_config: Bus, exc: Exception) -> str:
    hint = install_hint(bus_config.interface)
    needs = f"; {hint}" if hint else ""
    options = f", options {bus_config.options}" if bus_config.options else ""
    return (
        f"cannot open the CAN bus (interface {bus_config.interface}, channel {bus_config.channel!r}{options}): "
        f"{type(exc).__name__ + ': ' if isinstance(exc, NameError | AttributeError) else ''}{exc}{needs} "
        f"({DOCS}; {python_can_page(bus_config.interface)})"
    )


KERNEL_FILTERED = frozenset({"socketcan"})
"""python-can interfaces whose receive filters run in the kernel: a filtered socket gets its own queue."""
STANDARD_ID_MASK = 0x7FF
"""Every bit of an 11-bit identifier."""


def estop_channel_kwargs(bus_config: Bus) -> dict[str, Any] | None:
    """``can.Bus`` keyword arguments of an E-stop-only receive channel; None where filters are not in the kernel.

    On SocketCAN each socket has its own receive queue and the kernel filters
    before queueing, so a socket filtered to ``ESTOP_ID`` holds E-stops only,
    however full the main socket's queue is. On udp_multicast (every socket
    gets every datagram; python-can filters after reading) and virtual, a
    second socket would read the whole bus again for nothing: there the loops
    rely on draining fully with the E-stop first (:mod:`millctl.protocol.receive`).
    """
    kwargs = bus_kwargs(bus_config)
    if kwargs["interface"] not in KERNEL_FILTERED:
        return None
    kwargs["can_filters"] = [{"can_id": ESTOP_ID, "can_mask": STANDARD_ID_MASK, "extended": False}]
    kwargs["ignore_rx_error_frames"] = True  # the main socket reports error frames (bus health); this one E-stops only
    return kwargs


def open_estop_channel(bus_config: Bus) -> can.BusABC | None:
    """Open the E-stop-only receive channel (:func:`estop_channel_kwargs`), or None where there is none.

    A failure is a :class:`~millctl.errors.BusError` naming the bus, as for :func:`open_bus`.
    """
    kwargs = estop_channel_kwargs(bus_config)
    if kwargs is None:
        return None
    try:
        bus = can.Bus(**kwargs)
    except (can.CanError, OSError, ValueError, TypeError) as exc:
        raise BusError(
            f"cannot open the E-stop receive channel (interface {bus_config.interface}, channel "
            f"{bus_config.channel!r}, filter 0x{ESTOP_ID:03X}): {exc}"
        ) from exc
    log.info("opened the E-stop receive channel on %s (filter 0x%03X)", bus.channel_info, ESTOP_ID)
    return bus


__all__ = ["KERNEL_FILTERED", "bus_kwargs", "estop_channel_kwargs", "open_bus", "open_estop_channel"]
