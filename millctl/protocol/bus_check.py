"""``millctl bus check``: the configured bus up, healthy and at its bitrate, and the node answering.

It reads, without sending anything:

- for socketcan, the link as the kernel sees it (``ip -details -statistics
  -json link show DEV``): its state, its bitrate (set on the link, not by
  python-can: a bitrate other than ``bus.bitrate_bit_s`` is a problem) and the
  controller's error counters;
- the adapter's condition and error frames while listening
  (:class:`~millctl.protocol.bus_health.BusHealthMonitor`);
- whether the node is present: a NodeStatus (0x100) with a good CRC within the
  listening time, with the node's state.

Exit codes (docs/deployment.md#millctl-bus-check): 0 bus up and node present;
3 (``ExitCode.BUS``) a problem: bus-off, a link down or at another bitrate, or
the node silent (the bus that cannot be opened is a ``BusError``, 3 as well).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import can

from millctl.api.enums import BusCondition
from millctl.config.bus import Bus
from millctl.protocol.bus_health import BusHealthMonitor
from millctl.protocol.codec import Codec
from millctl.protocol.errors import ProtocolError
from millctl.protocol.messages import FaultCode, NodeStatus
from millctl.protocol.receive import BusReader

IP_TIMEOUT_S = 5.0
POLL_S = 0.01


@dataclass(frozen=True)
class LinkInfo:
    """A SocketCAN link as ``ip -details -statistics -json link show`` reports it."""

    kind: str
    """``can`` for a real controller, ``vcan`` for a virtual one."""
    operstate: str
    state: str | None
    """The CAN controller's state (ERROR-ACTIVE, ERROR-WARNING, ERROR-PASSIVE, BUS-OFF, STOPPED); None for vcan."""
    bitrate_bit_s: int | None
    data_bitrate_bit_s: int | None
    tx_error_counter: int | None
    rx_error_counter: int | None
    restart_ms: int | None
    bus_off: int | None
    """Times the controller went bus-off (``can_stats``)."""


def parse_link(text: str) -> LinkInfo:
    """Parse the JSON of ``ip -details -statistics -json link show DEV`` (one device)."""
    device: dict[str, Any] = json.loads(text)[0]
    linkinfo = device.get("linkinfo", {})
    info: dict[str, Any] = linkinfo.get("info_data", {}) or {}
    xstats: dict[str, Any] = linkinfo.get("info_xstats", {}) or {}
    berr = info.get("berr_counter", {}) or {}
    return LinkInfo(
        kind=str(linkinfo.get("info_kind", "unknown")),
        operstate=str(device.get("operstate", "UNKNOWN")),
        state=info.get("state"),
        bitrate_bit_s=(info.get("bittiming") or {}).get("bitrate"),
        data_bitrate_bit_s=(info.get("data_bittiming") or {}).get("bitrate"),
        tx_error_counter=berr.get("tx"),
        rx_error_counter=berr.get("rx"),
        restart_ms=info.get("restart_ms"),
        bus_off=xstats.get("bus_off"),
    )


def read_link(channel: str) -> LinkInfo | str:
    """The link of a SocketCAN device, or why it could not be read."""
    ip = shutil.which("ip")
    if ip is None:
        return "`ip` (iproute2) is not installed"
    try:
        done = subprocess.run([ip, "-details", "-statistics", "-json", "link", "show", "dev", channel],
                              capture_output=True, text=True, timeout=IP_TIMEOUT_S, check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"`ip link show {channel}` failed: {exc}"
    if done.returncode != 0:
        return f"`ip link show {channel}`: {done.stderr.strip() or f'exit {done.returncode}'}"
    try:
        return parse_link(done.stdout)
    except (ValueError, IndexError, KeyError, TypeError, AttributeError) as exc:
        return f"`ip -json link show {channel}` gave output that is not a link: {exc}"


def link_problems(link: LinkInfo, bus: Bus) -> list[str]:
    """What is wrong with a SocketCAN link for this configuration (empty: nothing)."""
    problems = []
    if link.operstate == "DOWN":
        problems.append(f"link {bus.channel} is DOWN: `sudo ip link set {bus.channel} up type can bitrate "
                        f"{bus.bitrate_bit_s}` (docs/deployment.md#2-the-can-adapter)")
    if link.state == "BUS-OFF":
        problems.append(f"link {bus.channel} is BUS-OFF (restart-ms {link.restart_ms}): check wiring, termination "
                        "and bitrate")
    if link.kind == "can" and link.bitrate_bit_s is not None and link.bitrate_bit_s != bus.bitrate_bit_s:
        problems.append(
            f"link {bus.channel} runs at {link.bitrate_bit_s} bit/s but bus.bitrate_bit_s = {bus.bitrate_bit_s}: "
            f"python-can's socketcan does not set the bitrate; set it on the link (`sudo ip link set "
            f"{bus.channel} down && sudo ip link set {bus.channel} up type can bitrate {bus.bitrate_bit_s}`) or "
            "correct the configuration (docs/deployment.md#2-the-can-adapter)"
        )
    return problems


def startup_link_problems(bus_config: Bus) -> list[str]:
    """For a socketcan bus, what is wrong with its link (bitrate, state) as the service starts; else nothing."""
    if bus_config.interface != "socketcan":
        return []
    link = read_link(bus_config.channel)
    if isinstance(link, str):
        return []  # not readable (no iproute2, a restricted sandbox): `millctl bus check` says why
    return link_problems(link, bus_config)


@dataclass
class BusCheckReport:
    """What ``millctl bus check`` found."""

    interface: str
    channel: str
    bitrate_bit_s: int
    listened_s: float
    link: dict[str, Any] | None = None
    link_note: str = ""
    health: dict[str, int | str | None] = field(default_factory=dict)
    node_present: bool = False
    node_state: str | None = None
    node_first_fault: str | None = None
    node_status_after_s: float | None = None
    frames: int = 0
    problems: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when nothing is wrong."""
        return not self.problems

    def as_dict(self) -> dict[str, Any]:
        """As plain data (``--json``)."""
        return {**asdict(self), "ok": self.ok}


def check_bus(bus_config: Bus, bus: can.BusABC, codec: Codec, listen_s: float) -> BusCheckReport:
    """Listen on an open bus for up to ``listen_s`` (until the first NodeStatus); report what was found."""
    report = BusCheckReport(bus_config.interface, bus_config.channel, bus_config.bitrate_bit_s, 0.0)
    if bus_config.interface == "socketcan":
        link = read_link(bus_config.channel)
        if isinstance(link, str):
            report.link_note = f"link not readable: {link}"
        else:
            report.link = asdict(link)
            report.problems.extend(link_problems(link, bus_config))
    monitor = BusHealthMonitor(bus, bus_config.interface)
    reader = BusReader(bus, "bus check")
    start = time.monotonic()
    while report.node_status_after_s is None and time.monotonic() - start < listen_s:
        batch = reader.drain()
        for error_frame in batch.error_frames:
            monitor.on_error_frame(error_frame)
        monitor.poll()
        for frame in batch.frames:
            if frame.arbitration_id != codec.frame_id(NodeStatus):
                continue
            try:
                decoded = codec.decode(frame)
            except ProtocolError:
                continue
            if isinstance(decoded.message, NodeStatus):
                report.node_present = True
                report.node_state = decoded.message.state.name
                report.node_first_fault = FaultCode(decoded.message.first_fault).name
                report.node_status_after_s = time.monotonic() - start
                break
        time.sleep(POLL_S)
    report.listened_s = time.monotonic() - start
    report.frames = reader.counts.frames
    report.health = monitor.health.as_dict()
    if monitor.health.condition is BusCondition.BUS_OFF:
        report.problems.append(f"the adapter is bus-off ({monitor.health.last_error or monitor.health.state_source})")
    if not report.node_present:
        hint = " (the virtual bus is in-process: the node runs inside `millctl serve`)" if (
            bus_config.interface == "virtual") else ": check power, wiring, termination, the node's bitrate"
        report.problems.append(
            f"no NodeStatus (0x100) from the node within {listen_s:g} s on {bus_config.interface}:"
            f"{bus_config.channel}, {report.frames} frame(s) heard{hint}"
        )
    return report


__all__ = [
    "BusCheckReport",
    "LinkInfo",
    "check_bus",
    "link_problems",
    "parse_link",
    "read_link",
    "startup_link_problems",
]
