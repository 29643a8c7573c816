"""``millctl_udp_multicast``: python-can's udp_multicast, made to behave like a real CAN bus.

Registered as the python-can interface ``millctl_udp_multicast`` (a
``can.interface`` entry point), so ``can.Bus(interface="millctl_udp_multicast",
channel="239.74.163.2", port=…, hop_limit=0)`` opens it. Two differences from
the stock interface, which it reuses for receiving and for the wire format
(so a stock ``udp_multicast`` bus, ``cantools monitor`` or ``can.logger`` can
listen in):

- **No self-echo.** A real CAN controller does not hand its own frames back;
  the stock interface does, because the host loops multicast back to every
  member of the group. This bus sends from a socket of its own (an ephemeral
  port) and drops every received datagram from that port.
- **Room between drains.** Its receive socket asks for a 1 MiB buffer
  (``receive_buffer_bytes``; the kernel caps it at ``net.core.rmem_max``),
  so a burst of about a thousand datagrams between two drains is not lost.
- **Never off the host.** It refuses to open unless ``hop_limit`` (the IPv4
  TTL / IPv6 hop limit) is 0, so no frame is ever forwarded by a router; and
  by default it also refuses unless ``lo`` is the only network interface (a
  private network namespace, e.g. ``unshare -rn``), so no other process on a
  shared machine hears it. Pass ``private_netns_only=False`` to use it in a
  namespace with other interfaces (still TTL 0, still this host only).
"""

from __future__ import annotations

import ipaddress
import logging
import socket
import time
from typing import Any

import can
from can.interfaces.udp_multicast import UdpMulticastBus
from can.interfaces.udp_multicast.utils import pack_message, unpack_message
from can.typechecking import AutoDetectedConfig

log = logging.getLogger(__name__)

INTERFACE_NAME = "millctl_udp_multicast"
DEFAULT_GROUP = "239.74.163.2"
"""An administratively scoped IPv4 group (the same as python-can's IPv4 default)."""
DEFAULT_PORT = 43113
RECEIVE_BUFFER_BYTES = 1 << 20
"""Receive buffer asked for (bytes; the kernel caps it at net.core.rmem_max): ~1000 datagrams between two drains."""


def private_netns_problem() -> str | None:
    """Why this network namespace is not private (interfaces other than ``lo``), or None."""
    names = sorted(name for _, name in socket.if_nameindex())
    if names == ["lo"]:
        return None
    return (
        f"this network namespace has the interfaces {', '.join(names)}; {INTERFACE_NAME} runs only where lo is "
        "the sole interface (e.g. `unshare -rn`, see tests/hil/in_netns), or pass private_netns_only=False"
    )


def check_multicast_safe(channel: str, hop_limit: int, private_netns_only: bool = True) -> ipaddress._BaseAddress:
    """Refuse (``CanInitializationError``) a group that is not multicast, a hop limit ≠ 0, or a shared netns."""
    try:
        group = ipaddress.ip_address(channel)
    except ValueError:
        raise can.CanInitializationError(
            f"{INTERFACE_NAME}: channel {channel!r} is not an IP address; use a multicast group such as {DEFAULT_GROUP}"
        ) from None
    if not group.is_multicast:
        raise can.CanInitializationError(f"{INTERFACE_NAME}: channel {channel} is not a multicast group")
    if isinstance(hop_limit, bool) or hop_limit != 0:
        raise can.CanInitializationError(
            f"{INTERFACE_NAME}: hop_limit (TTL) = {hop_limit!r}, must be 0 so that no frame leaves this host; "
            "set [bus.options] hop_limit = 0"
        )
    if private_netns_only and (problem := private_netns_problem()):
        raise can.CanInitializationError(f"{INTERFACE_NAME}: refusing to send multicast: {problem}")
    return group


class EchoFreeUdpMulticastBus(UdpMulticastBus):
    """A udp_multicast bus that never receives its own frames and never sends beyond this host."""

    def __init__(
        self,
        channel: str = DEFAULT_GROUP,
        port: int = DEFAULT_PORT,
        hop_limit: int | None = None,
        receive_own_messages: bool = False,
        fd: bool = False,
        private_netns_only: bool = True,
        receive_buffer_bytes: int = RECEIVE_BUFFER_BYTES,
        **kwargs: Any,
    ) -> None:
        if hop_limit is None:
            raise can.CanInitializationError(
                f"{INTERFACE_NAME}: hop_limit must be given explicitly and be 0 (no frame may leave this host)"
            )
        group = check_multicast_safe(channel, hop_limit, private_netns_only)
        super().__init__(
            channel=channel, port=port, hop_limit=0, receive_own_messages=receive_own_messages, fd=fd, **kwargs
        )
        family = socket.AF_INET if group.version == 4 else socket.AF_INET6
        self._tx = socket.socket(family, socket.SOCK_DGRAM)
        try:
            self._multicast._socket.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer_bytes)
            if family == socket.AF_INET:
                self._tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 0)
                self._tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
            else:
                self._tx.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_MULTICAST_HOPS, 0)
                self._tx.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_MULTICAST_LOOP, 1)
            self._tx.bind(("", 0))
        except OSError as exc:
            self._tx.close()
            super().shutdown()
            raise can.CanInitializationError(f"{INTERFACE_NAME}: cannot open the sending socket: {exc}") from exc
        self._tx_port: int = self._tx.getsockname()[1]
        self._destination = (channel, port)
        self._tx_timeout: float | None = None
        self.receive_buffer_bytes: int = self._multicast._socket.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        """The receive buffer the kernel granted (bytes; Linux reports twice what it was asked, up to its cap)."""
        self.channel_info = f"{INTERFACE_NAME} {channel}:{port} (TTL 0, no self-echo)"

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send one frame to the group, from the socket whose echo this bus drops."""
        if msg.is_fd and not self._can_protocol == can.CanProtocol.CAN_FD:
            raise can.CanOperationError("cannot send an FD frame on a classic CAN bus")
        data = pack_message(msg)
        if timeout != self._tx_timeout:
            self._tx.settimeout(timeout)
            self._tx_timeout = timeout
        try:
            sent = self._tx.sendto(data, self._destination)
        except TimeoutError:
            raise can.CanTimeoutError() from None
        except OSError as exc:
            raise can.CanOperationError(f"{INTERFACE_NAME}: send failed: {exc}") from exc
        if sent < len(data):
            raise can.CanTimeoutError()

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        """The next datagram that is not this bus's own echo, waiting at most ``timeout`` for it.

        Own echoes are dropped *inside* this loop, so a call with timeout 0
        reads past every echo already queued and returns None only when
        nothing foreign is left (a drain empties the socket however many
        frames this bus sent since the last one: SAFETY.md item 22). A
        datagram that is not a frame raises ``CanOperationError`` (it is
        consumed; the next call reads on); a frame is handed on as it came
        (an FD or remote frame, say) for the receiver's codec to judge.
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            result = self._multicast.recv(left)
            if not result:
                return None, False
            data, sender, timestamp = result
            if sender[1] != self._tx_port:
                break
        try:
            message = unpack_message(data, replace={"timestamp": timestamp}, check=True)
        except Exception as exc:
            raise can.CanOperationError(
                f"{INTERFACE_NAME}: undecodable datagram of {len(data)} bytes from {sender[0]}:{sender[1]}: "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        return message, False

    def shutdown(self) -> None:
        """Close both sockets (never raises)."""
        tx = getattr(self, "_tx", None)
        if tx is not None:
            try:
                tx.close()
            except OSError as exc:
                log.warning("closing the sending socket failed: %s", exc)
        super().shutdown()

    @staticmethod
    def _detect_available_configs() -> list[AutoDetectedConfig]:
        return []


__all__ = [
    "DEFAULT_GROUP",
    "DEFAULT_PORT",
    "INTERFACE_NAME",
    "EchoFreeUdpMulticastBus",
    "check_multicast_safe",
    "private_netns_problem",
]
