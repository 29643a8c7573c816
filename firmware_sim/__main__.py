"""``python -m firmware_sim``: run the simulated node on the real clock until SIGINT/SIGTERM.

Exit codes (millctl.errors.ExitCode): 0 after a clean shutdown (motors ramped
down, heater off, bus shut down), 1 for bad arguments or configuration, 3
when the bus cannot be opened, 4 for an internal error.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import time
import typing
from collections.abc import Sequence
from types import FrameType

from firmware_sim.furnace_node import FurnaceNode
from firmware_sim.node import Node
from millctl.clock import MonotonicClock
from millctl.config import load_config
from millctl.config.models import Bus, DriveBackend
from millctl.errors import ExitCode, MillctlError
from millctl.protocol.factory import open_bus, open_estop_channel

log = logging.getLogger("firmware_sim")

SHUTDOWN_BOUND_S = 30.0
"""At most this long (s) is spent ramping the motors down after SIGINT/SIGTERM."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors exit with 1 (invalid input), not argparse's 2."""

    def error(self, message: str) -> typing.NoReturn:
        self.print_usage(sys.stderr)
        self.exit(int(ExitCode.INVALID_INPUT), f"{self.prog}: error: {message}\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="python -m firmware_sim",
        description="Simulated motor/furnace CAN node of the rod mill (docs/operations.md#simulated-node).",
        epilog="Exit codes: 0 ok, 1 invalid input, 3 bus error, 4 internal error.",
    )
    parser.add_argument("--config", required=True, help="mill configuration file (TOML)")
    parser.add_argument("--interface", help="python-can interface, overrides [bus].interface")
    parser.add_argument("--channel", help="bus channel (e.g. vcan0), overrides [bus].channel")
    parser.add_argument(
        "--furnace-only", action="store_true",
        help="the millbus node in its furnace-only mode on [drives.furnace_bus] (CiA 402 drives with "
        'furnace = "millbus"); --interface/--channel override that bus',
    )
    parser.add_argument("--fault-injection", action="store_true", help="honour SimFault frames (0x700–0x7FF)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the sensor noise and injected faults")
    parser.add_argument(
        "--lie-readback",
        action="append",
        default=[],
        metavar="MOTOR:INDEX",
        help="CiA 402 drives, with --fault-injection: SDO reads of this object return what was written + 1 "
        "(e.g. rotary:0x607F); repeatable",
    )
    parser.add_argument("--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    return parser


class _Stop:
    """Set by SIGINT/SIGTERM (``requested``)."""

    def __init__(self) -> None:
        self.requested = False

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        log.info("signal %s: stopping", signal.Signals(signum).name)
        self.requested = True


def _run(node: Node, tick_s: float, stop: _Stop) -> None:
    """Tick on the real clock, sleeping until each next tick (not a fixed sleep), until stopped."""
    next_s = time.monotonic()
    while not stop.requested:
        node.tick()
        next_s += tick_s
        delay = next_s - time.monotonic()
        if delay > 0.0:
            time.sleep(delay)
        elif delay < -tick_s:
            next_s = time.monotonic()  # overran by more than a tick: re-phase rather than catch up in a burst


def _shutdown(node: Node, tick_s: float) -> None:
    """Ramp the motors down (controlled stop), heater off, stepping ticks until standstill or the bound."""
    node.shutdown_stop()
    deadline = time.monotonic() + SHUTDOWN_BOUND_S
    while not node.at_standstill and time.monotonic() < deadline:
        node.tick()
        time.sleep(tick_s)
    counts = node.reader.counts
    log.info(
        "shut down: speeds %.1f/%.1f rpm, heater %s, %d ticks, mean %.3f ms, max %.3f ms; "
        "frames read %d (E-stops %d, malformed %d, error frames %d), receive errors %d, capped drains %d",
        *node.true_speeds_rpm,
        "on" if node.heater_on else "off",
        node.tick_count,
        node.tick_mean_s * 1e3,
        node.tick_max_s * 1e3,
        counts.frames,
        counts.estops,
        counts.malformed,
        counts.error_frames,
        counts.receive_errors,
        counts.capped_drains,
    )


def _bus_config(configured: Bus, interface: str | None, channel: str | None) -> Bus:
    """The config's bus with the command line's overrides; another interface drops the config's options."""
    if not interface and not channel:
        return configured
    values = configured.model_dump()
    if interface and interface != configured.interface:
        values.update(interface=interface, options={})
    if channel:
        values["channel"] = channel
    return Bus.model_validate(values)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the process exit code."""
    args = _parser().parse_args(argv)
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:
        config = load_config(args.config).config
        configured = config.drives.furnace_bus if args.furnace_only else config.bus
        if configured is None:
            log.error('--furnace-only needs [drives.furnace_bus] (backend = "cia402", furnace = "millbus")')
            return int(ExitCode.INVALID_INPUT)
        bus_config = _bus_config(configured, args.interface, args.channel)
        bus = open_bus(bus_config)
    except MillctlError as exc:
        log.error("%s", exc)
        return int(exc.exit_code)
    except ValueError as exc:  # pydantic's ValidationError of an override
        log.error("invalid --interface/--channel: %s", exc)
        return int(ExitCode.INVALID_INPUT)
    try:
        estop_bus = open_estop_channel(bus_config)  # a flood cannot crowd an E-stop out of its own queue
    except MillctlError as exc:
        bus.shutdown()
        log.error("%s", exc)
        return int(exc.exit_code)
    stop = _Stop()
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    if config.drives.backend is DriveBackend.CIA402 and not args.furnace_only:
        if estop_bus is not None:
            estop_bus.shutdown()
        from firmware_sim.cia402.process import run_cia402  # canopen only for this backend (issue 36, part 5)

        return run_cia402(config, bus, bus_config, args, stop)
    if args.lie_readback:
        bus.shutdown()
        if estop_bus is not None:
            estop_bus.shutdown()
        log.error("--lie-readback needs CiA 402 drives ([drives] backend = \"cia402\")")
        return int(ExitCode.INVALID_INPUT)
    node = (FurnaceNode if args.furnace_only else Node)(
        config, bus, MonotonicClock(), fault_injection=args.fault_injection, seed=args.seed, estop_bus=estop_bus
    )
    try:
        log.info("node on %s %s, tick %.3f s", bus_config.interface, bus_config.channel, config.timing.node_tick_s)
        _run(node, config.timing.node_tick_s, stop)
        _shutdown(node, config.timing.node_tick_s)
    finally:
        node.close()
        bus.shutdown()
        if estop_bus is not None:
            estop_bus.shutdown()
    return int(ExitCode.OK)


if __name__ == "__main__":
    sys.exit(main())
