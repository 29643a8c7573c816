"""``python -m firmware_sim`` with ``[drives] backend = "cia402"``: the simulated drives as a process.

Ticked on the real clock at ``timing.node_tick_s`` until SIGINT/SIGTERM,
then a quick stop on both drives, ticked until standstill (or
``SHUTDOWN_BOUND_S``), and the bus shut down. Exit codes as the millbus node's.
"""

from __future__ import annotations

import argparse
import logging
import time
from typing import Protocol

import can

from firmware_sim.cia402.mill import Cia402Mill
from millctl.clock import MonotonicClock
from millctl.config.models import Bus, MillConfig
from millctl.errors import ExitCode, MillctlError

log = logging.getLogger("firmware_sim")

SHUTDOWN_BOUND_S = 30.0
"""At most this long (s) is spent stopping the motors after SIGINT/SIGTERM."""
MOTORS = ("rotary", "vibration")


class StopFlag(Protocol):
    """Set by a signal handler."""

    requested: bool


def parse_lie(spec: str) -> tuple[str, int]:
    """``MOTOR:INDEX`` (INDEX hex like 0x607F, or decimal) → (motor, index); ValueError naming what is wrong."""
    motor, _, index = spec.partition(":")
    if motor not in MOTORS or not index:
        raise ValueError(f"--lie-readback {spec!r}: expected MOTOR:INDEX with MOTOR one of {', '.join(MOTORS)}")
    try:
        value = int(index, 0)
    except ValueError:
        raise ValueError(f"--lie-readback {spec!r}: {index!r} is not an object index (e.g. 0x607F)") from None
    if not 0x1000 <= value <= 0xFFFF:
        raise ValueError(f"--lie-readback {spec!r}: index 0x{value:X} is outside 0x1000–0xFFFF")
    return motor, value


def run_cia402(config: MillConfig, bus: can.BusABC, bus_config: Bus, args: argparse.Namespace, stop: StopFlag) -> int:
    """Run both simulated drives on ``bus`` until ``stop.requested``; the process exit code."""
    try:
        lies = [parse_lie(spec) for spec in args.lie_readback]
        if lies and not args.fault_injection:
            raise ValueError("--lie-readback is a fault injection: add --fault-injection")
    except ValueError as exc:
        bus.shutdown()
        log.error("%s", exc)
        return int(ExitCode.INVALID_INPUT)
    try:
        mill = Cia402Mill(config, bus, MonotonicClock(), fault_injection=args.fault_injection, seed=args.seed)
    except MillctlError as exc:  # an unreadable EDS
        bus.shutdown()
        log.error("%s", exc)
        return int(exc.exit_code)
    for motor, index in lies:
        mill.drives[motor].lie_readback(index)
        log.warning("fault injection: %s drive reads back 0x%04X as written + 1", motor, index)
    tick_s = config.timing.node_tick_s
    try:
        log.info("CiA 402 drives on %s %s, tick %.3f s", bus_config.interface, bus_config.channel, tick_s)
        next_s = time.monotonic()
        while not stop.requested:
            mill.tick()
            next_s += tick_s
            delay = next_s - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
            elif delay < -tick_s:
                next_s = time.monotonic()  # overran by more than a tick: re-phase rather than catch up
        mill.shutdown_stop()
        deadline = time.monotonic() + SHUTDOWN_BOUND_S
        while not mill.at_standstill and time.monotonic() < deadline:
            mill.tick()
            time.sleep(tick_s)
        log.info(
            "shut down: speeds %.1f/%.1f rpm, %d ticks, frames read %d (malformed %d), sent %d, send errors %d",
            *mill.true_speeds_rpm, mill.tick_count, mill.frames_read, mill.malformed, mill.out.frames_sent,
            mill.out.tx_errors,
        )
    finally:
        mill.close()
        bus.shutdown()
    return int(ExitCode.OK)


__all__ = ["SHUTDOWN_BOUND_S", "parse_lie", "run_cia402"]
