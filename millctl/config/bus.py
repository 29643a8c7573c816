"""The ``[bus]`` section: the python-can interface, its channel, bitrate, CAN FD flags and options.

Every interface python-can knows (``can.interfaces.VALID_INTERFACES``) is
accepted; what can be checked before the adapter is opened is checked here,
each error naming the field, the value, the bound and where to read more
(docs/deployment.md#2-the-can-adapter and python-can's page of the interface):

- the **channel** in the interface's own format: a Linux network device for
  socketcan (``can0``), ``PCAN_USBBUS1`` … for pcan, a channel number for
  kvaser, vector (or ``"0, 1"``), gs_usb and the other numbered adapters, a
  serial port or URL for slcan (``/dev/ttyACM0``, ``COM4``, ``socket://host:port``,
  optionally ``@115200``);
- the **bitrate**: classic CAN, 5 kbit/s … 1 Mbit/s; pcan and slcan take
  only their drivers' table of rates (pcan silently falls back to 500 kbit/s
  for any other value, so an unlisted one is refused here);
- **CAN FD**: the mill's frames are classic CAN (config/millbus.dbc); ``fd``
  only lets the adapter share a bus with FD traffic, on the interfaces whose
  python-can driver takes ``fd`` and ``data_bitrate`` (or, for socketcan,
  whose link sets ``dbitrate``);
- **options**: no key that a field of this section owns, nothing that would
  make the controller deaf (``ignore_rx_error_frames``) or mute (listen-only),
  and no near-miss of a known option name (a typo python-can would ignore).

SocketCAN's bitrate is set on the link (``ip link set can0 type can bitrate
N``), not by python-can: ``millctl bus check`` compares it with
``bitrate_bit_s``.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Callable
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

DOCS = "docs/deployment.md#2-the-can-adapter"


def python_can_page(interface: str) -> str:
    """python-can's documentation page of an interface."""
    page = {"udp_multicast": "udp_multicast", "millctl_udp_multicast": "udp_multicast", "gs_usb": "gs_usb"}.get(
        interface, interface
    )
    return f"https://python-can.readthedocs.io/en/stable/interfaces/{page}.html"


def known_interfaces() -> frozenset[str]:
    """Every interface name python-can's registry knows (``can.interfaces.VALID_INTERFACES``)."""
    from can.interfaces import VALID_INTERFACES

    return frozenset(VALID_INTERFACES)


CLASSIC_MIN_BIT_S = 5_000
CLASSIC_MAX_BIT_S = 1_000_000
"""Classic CAN's bitrate range (ISO 11898-1 allows up to 1 Mbit/s)."""
FD_DATA_MAX_BIT_S = 10_000_000
"""The fastest CAN FD data phase any adapter here offers."""

INTERFACE_BITRATES_BIT_S: dict[str, frozenset[int]] = {
    # can.interfaces.pcan.basic.PCAN_BITRATES: any other value silently becomes 500 kbit/s
    "pcan": frozenset({1_000_000, 800_000, 500_000, 250_000, 125_000, 100_000, 95_000, 83_000, 50_000, 47_000,
                       33_000, 20_000, 10_000, 5_000}),
    # can.interfaces.slcan.slcanBus._BITRATES (the S0 … S9 commands)
    "slcan": frozenset({10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 750_000, 1_000_000, 83_300}),
}
"""Interfaces that take only a table of bitrates (a unit test holds these to python-can's own tables)."""

FD_INTERFACES = frozenset({"socketcan", "vector", "kvaser", "virtual", "udp_multicast", "millctl_udp_multicast"})
"""Interfaces whose python-can driver takes ``fd`` (and ``data_bitrate`` where the adapter sets it)."""
FD_DATA_BITRATE_KWARG = frozenset({"vector", "kvaser"})
"""Interfaces whose driver takes the data-phase bitrate as the ``data_bitrate`` keyword."""

NUMBERED_CHANNEL = frozenset({"kvaser", "gs_usb", "ixxat", "systec", "canalystii", "neovi", "usb2can", "cantact"})
"""Interfaces whose channel is a channel (or device) number ≥ 0."""

_OWNED_OPTIONS = {
    "interface": "set bus.interface instead",
    "bustype": "set bus.interface instead",
    "channel": "set bus.channel instead",
    "bitrate": "set bus.bitrate_bit_s instead",
    "fd": "set bus.fd instead",
    "data_bitrate": "set bus.data_bitrate_bit_s instead",
    "receive_own_messages": "the controller must never hear its own frames (the bus log records them as Tx)",
    "ignore_rx_error_frames": "error frames are how bus errors and bus-off are seen (docs/protocol.md#bus-errors)",
    "listen_only": "a listen-only adapter cannot send the controller's heartbeat",
    "state": "a passive (listen-only) adapter cannot send the controller's heartbeat",
}
"""Options that a field of this section sets, or that would blind or mute the controller."""

KNOWN_OPTIONS: dict[str, frozenset[str]] = {
    "socketcan": frozenset({"local_loopback", "can_filters"}),
    "pcan": frozenset({"device_id", "timing", "auto_reset", "f_clock", "f_clock_mhz", "nom_brp", "nom_tseg1",
                       "nom_tseg2", "nom_sjw", "data_brp", "data_tseg1", "data_tseg2", "data_sjw"}),
    "kvaser": frozenset({"can_filters", "timing", "accept_virtual", "tseg1", "tseg2", "sjw", "no_samp", "driver_mode",
                         "single_handle", "exclusive", "override_exclusive", "data_tseg1", "data_tseg2",
                         "data_sjw"}),
    "vector": frozenset({"can_filters", "poll_interval", "timing", "rx_queue_size", "app_name", "serial",
                         "sjw_abr", "tseg1_abr", "tseg2_abr", "sjw_dbr", "tseg1_dbr", "tseg2_dbr"}),
    "slcan": frozenset({"tty_baudrate", "timing", "sleep_after_open", "rtscts", "timeout"}),
    "gs_usb": frozenset({"index", "bus", "address", "can_filters"}),
    "virtual": frozenset({"rx_queue_size", "preserve_timestamps", "protocol"}),
    "udp_multicast": frozenset({"port", "hop_limit"}),
    "millctl_udp_multicast": frozenset({"port", "hop_limit", "private_netns_only", "receive_buffer_bytes"}),
}
"""Named options of the common interfaces' python-can constructors (a near-miss of one is refused as a typo)."""

_IFNAME = re.compile(r"[^\s/:]{1,15}")
"""A Linux network device name: at most 15 bytes, no white space, '/' or ':' (IFNAMSIZ)."""
_PCAN_CHANNEL = re.compile(r"PCAN_(USBBUS|PCIBUS|LANBUS)([1-9]|1[0-6])|PCAN_ISABUS[1-8]|PCAN_DNGBUS1|PCAN_PCCBUS[12]")
"""can.interfaces.pcan.basic.PCAN_CHANNEL_NAMES (PCAN_NONEBUS aside)."""
_SERIAL_PORT = re.compile(r"(/dev/\S+|COM[1-9][0-9]*|(socket|rfc2217|loop|spy|hwgrep|alt)://\S*)(@[1-9][0-9]*)?")
"""An slcan channel: a serial device, a Windows COM port or a pyserial URL, with an optional ``@baud``."""


def _where(interface: str) -> str:
    return f"{DOCS}; {python_can_page(interface)}"


def _vector_channel(channel: str) -> bool:
    return all(part.strip().isdigit() for part in channel.split(","))


_CHANNEL_FORMAT: dict[str, tuple[Callable[[str], bool], str]] = {
    "socketcan": (
        lambda c: bool(_IFNAME.fullmatch(c)) and c not in (".", ".."),
        "is not a Linux network device name (≤ 15 characters, no white space, '/' or ':'), e.g. can0",
    ),
    "pcan": (
        lambda c: bool(_PCAN_CHANNEL.fullmatch(c)),
        "is not a PCAN channel name: PCAN_USBBUS1 … PCAN_USBBUS16, PCAN_PCIBUS1 …, PCAN_LANBUS1 …",
    ),
    "vector": (_vector_channel, 'is not a channel number or a comma-separated list of them (0, or "0, 1")'),
    "slcan": (
        lambda c: bool(_SERIAL_PORT.fullmatch(c)),
        "is not a serial port: /dev/ttyACM0, /dev/serial/by-id/…, COM4 or socket://host:port, optionally "
        "followed by @<tty baud rate>",
    ),
    **{name: (str.isdigit, "is not a channel number (0, 1, …)") for name in NUMBERED_CHANNEL},
}
"""Per interface: the channel's format and what to say when a channel does not fit it."""


def channel_problem(interface: str, channel: str) -> str | None:
    """Why ``channel`` is not a channel of ``interface`` (None when it is, or the format is not checked)."""
    check = _CHANNEL_FORMAT.get(interface)
    if check is None or check[0](channel):
        return None
    return check[1]


def _typo(key: str, known: frozenset[str]) -> str | None:
    if key in known:
        return None
    close = difflib.get_close_matches(key, sorted(known), n=1, cutoff=0.75)
    return close[0] if close else None


class Bus(BaseModel):
    """The CAN bus, as python-can sees it (turned into a ``can.Bus`` in one place, ``millctl.protocol.factory``)."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)

    interface: str = "virtual"
    """A python-can interface name (``can.interfaces.VALID_INTERFACES``): socketcan, pcan, kvaser, vector, slcan …"""
    channel: str = "millbus"
    """The channel in the interface's format (a whole number in TOML is taken as its digits)."""
    bitrate_bit_s: Annotated[int, Field(ge=CLASSIC_MIN_BIT_S, le=CLASSIC_MAX_BIT_S)] = 500_000
    """The (nominal) bitrate; socketcan: documents the link's own, which ``millctl bus check`` compares."""
    fd: bool = False
    """Open the adapter in CAN FD mode (the mill's own frames stay classic CAN)."""
    data_bitrate_bit_s: Annotated[int, Field(gt=0, le=FD_DATA_MAX_BIT_S)] | None = None
    """CAN FD data-phase bitrate (only with ``fd``)."""
    options: dict[str, Any] = Field(default_factory=dict)
    """Further keyword arguments of the python-can interface (e.g. slcan's ``tty_baudrate``, vector's ``app_name``)."""

    @field_validator("interface")
    @classmethod
    def _known_interface(cls, value: str) -> str:
        known = known_interfaces()
        if value not in known:
            close = difflib.get_close_matches(value, sorted(known), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ValueError(
                f"not a python-can interface{hint}; known: {', '.join(sorted(known))} "
                f"({DOCS}; https://python-can.readthedocs.io/en/stable/interfaces.html)"
            )
        return value

    @field_validator("channel", mode="before")
    @classmethod
    def _channel_text(cls, value: object) -> object:
        if isinstance(value, int) and not isinstance(value, bool):
            return str(value)
        return value

    @field_validator("channel")
    @classmethod
    def _channel_nonempty(cls, value: str) -> str:
        if not value.strip():
            raise ValueError(f"channel must not be empty ({DOCS})")
        return value

    @model_validator(mode="after")
    def _consistent(self) -> Bus:
        interface, channel = self.interface, self.channel
        problem = channel_problem(interface, channel)
        if problem is not None:
            raise ValueError(f"bus.channel = {channel!r} {problem} for interface {interface} ({_where(interface)})")
        table = INTERFACE_BITRATES_BIT_S.get(interface)
        if table is not None and self.bitrate_bit_s not in table:
            raise ValueError(
                f"bus.bitrate_bit_s = {self.bitrate_bit_s} is not a bitrate of interface {interface}: one of "
                f"{', '.join(str(b) for b in sorted(table))} ({_where(interface)})"
            )
        self._check_fd()
        self._check_options()
        return self

    def _check_fd(self) -> None:
        interface = self.interface
        if self.fd and interface not in FD_INTERFACES:
            raise ValueError(
                f"bus.fd = true is not supported here for interface {interface} (CAN FD with: "
                f"{', '.join(sorted(FD_INTERFACES))}); the mill's frames are classic CAN, so fd = false works on "
                f"any bus ({_where(interface)})"
            )
        data = self.data_bitrate_bit_s
        if data is not None and not self.fd:
            raise ValueError(f"bus.data_bitrate_bit_s = {data} needs bus.fd = true ({_where(interface)})")
        if data is not None and data < self.bitrate_bit_s:
            raise ValueError(
                f"bus.data_bitrate_bit_s = {data} must be ≥ bus.bitrate_bit_s = {self.bitrate_bit_s}: the data "
                f"phase is the fast one ({_where(interface)})"
            )
        if self.fd and interface in FD_DATA_BITRATE_KWARG and data is None:
            raise ValueError(
                f"bus.fd = true on interface {interface} needs bus.data_bitrate_bit_s (e.g. 2000000) "
                f"({_where(interface)})"
            )

    def _check_options(self) -> None:
        interface = self.interface
        known = KNOWN_OPTIONS.get(interface, frozenset())
        for key, value in self.options.items():
            if key in _OWNED_OPTIONS:
                raise ValueError(
                    f"bus.options.{key} = {value!r} is not allowed: {_OWNED_OPTIONS[key]} ({_where(interface)})"
                )
            close = _typo(key, known)
            if close is not None:
                raise ValueError(
                    f"bus.options.{key} = {value!r} is not an option of interface {interface} (did you mean "
                    f"{close!r}? python-can ignores unknown options) ({_where(interface)})"
                )
        baud = self.options.get("tty_baudrate")
        if baud is not None and (isinstance(baud, bool) or not isinstance(baud, int) or baud <= 0):
            raise ValueError(
                f"bus.options.tty_baudrate = {baud!r} must be a whole number of baud > 0 (the serial link's speed, "
                f"e.g. 115200) ({_where(interface)})"
            )
        app = self.options.get("app_name")
        if app is not None and not isinstance(app, str):
            raise ValueError(
                f"bus.options.app_name = {app!r} must be text: the application name in Vector Hardware Config "
                f"({_where(interface)})"
            )

    @property
    def real(self) -> bool:
        """True for an adapter on a real bus (not the in-process virtual bus or the multicast test transports)."""
        return self.interface not in ("virtual", "udp_multicast", "millctl_udp_multicast")


__all__ = [
    "CLASSIC_MAX_BIT_S",
    "CLASSIC_MIN_BIT_S",
    "DOCS",
    "FD_DATA_BITRATE_KWARG",
    "FD_INTERFACES",
    "INTERFACE_BITRATES_BIT_S",
    "KNOWN_OPTIONS",
    "NUMBERED_CHANNEL",
    "Bus",
    "channel_problem",
    "known_interfaces",
    "python_can_page",
]
