"""``millctl bus log show`` and ``bus monitor``: every frame with its words, millbus and CANopen side by side."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from millctl.cli.output import stderr_console, stdout_console
from millctl.errors import ExitCode, InvalidInputError

if TYPE_CHECKING:
    import can


def add_view_commands(
    bus_sub: argparse._SubParsersAction[argparse.ArgumentParser],
    log_sub: argparse._SubParsersAction[argparse.ArgumentParser],
) -> None:
    """Add ``bus log show FILE`` and ``bus monitor``."""
    show = log_sub.add_parser(
        "show", help="every frame of a bus log with what it says (millbus DBC and CANopen)",
        description="Read a bus log (.log candump, .asc, .blf, .trc, .csv) and print each frame with its decoding: "
        "the millbus DBC's messages, and CANopen's NMT, heartbeat, PDO, SDO and EMCY (docs/protocol.md#cia-402). "
        "The config's [drives] backend says which is tried first.",
    )
    show.add_argument("input", help="bus log to read")
    show.add_argument("--limit", type=int, default=0, metavar="N", help="print at most N frames (0: all)")
    show.add_argument("--json", action="store_true", help="one JSON object per frame")
    show.set_defaults(handler=_show)
    monitor = bus_sub.add_parser(
        "monitor", help="listen on the configured bus and print each frame with what it says (sends nothing)",
        description="Open the configured bus, listen, and print each frame decoded as in `bus log show`, until "
        "--duration-s or Ctrl+C.",
    )
    monitor.add_argument("--duration-s", type=float, default=0.0, metavar="S", help="stop after S seconds (0: never)")
    monitor.add_argument("--json", action="store_true", help="one JSON object per frame")
    monitor.set_defaults(handler=_monitor)


def _describer(args: argparse.Namespace) -> Any:
    from millctl.config import load_config
    from millctl.drives.cia402.frames import describe_frame
    from millctl.protocol import default_codec

    config = load_config(args.config).config
    codec, canopen = default_codec(), config.drives.backend == "cia402"
    controller_id = config.drives.controller_node_id

    def describe(frame: can.Message) -> str:
        return describe_frame(frame, codec, canopen=canopen, controller_id=controller_id)

    return describe


def _line(frame: can.Message, words: str, as_json: bool) -> str:
    if as_json:
        return json.dumps({"t_s": frame.timestamp, "id": frame.arbitration_id, "data": bytes(frame.data).hex(),
                           "rx": frame.is_rx, "decoded": words})
    return f"{frame.timestamp:17.6f}  {frame.arbitration_id:03X}  {bytes(frame.data).hex(' '):<23}  {words}"


def _show(args: argparse.Namespace) -> int:
    import can

    path = Path(args.input)
    if not path.is_file():
        raise InvalidInputError(f"{path}: no such bus log (millctl writes them to records/bus/*.log)")
    describe, out = _describer(args), stdout_console()
    shown = 0
    with can.LogReader(str(path)) as reader:
        for frame in reader:
            if frame.is_error_frame:
                continue
            out.print(_line(frame, describe(frame), args.json), markup=False, highlight=False, soft_wrap=True)
            shown += 1
            if args.limit and shown >= args.limit:
                break
    return int(ExitCode.OK)


def _monitor(args: argparse.Namespace) -> int:
    from millctl.config import load_config
    from millctl.protocol import open_bus

    describe, out = _describer(args), stdout_console()
    bus = open_bus(load_config(args.config).config.bus)
    end = time.monotonic() + args.duration_s if args.duration_s > 0 else float("inf")
    try:
        while time.monotonic() < end:
            frame = bus.recv(timeout=min(0.2, max(end - time.monotonic(), 0.0)))
            if frame is None or frame.is_error_frame:
                continue
            out.print(_line(frame, describe(frame), args.json), markup=False, highlight=False, soft_wrap=True)
    except KeyboardInterrupt:
        stderr_console().print("monitor stopped", markup=False)
    finally:
        bus.shutdown()
    return int(ExitCode.OK)


__all__ = ["add_view_commands"]
