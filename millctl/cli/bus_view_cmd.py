"""``millctl bus log show`` and ``bus monitor``: every frame with its words, millbus and CANopen side by side."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from millctl.cli.output import print_json, stderr_console, stdout_console
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
    show.add_argument("--json", action="store_true",
                      help="one JSON document whose result lists the frames (time, channel, ID, data, decoding)")
    show.set_defaults(handler=_show)
    monitor = bus_sub.add_parser(
        "monitor", help="listen on the configured bus and print each frame with what it says (sends nothing)",
        description="Open the configured bus, listen, and print each frame decoded as in `bus log show`, until "
        "--duration-s or Ctrl+C.",
    )
    monitor.add_argument("--duration-s", type=float, default=0.0, metavar="S", help="stop after S seconds (0: never)")
    monitor.add_argument("--json", action="store_true",
                         help="one JSON document when the monitor stops, listing the frames heard (give --duration-s)")
    monitor.set_defaults(handler=_monitor)


def _describer(args: argparse.Namespace) -> Any:
    from millctl.config import load_config
    from millctl.drives.cia402.frames import describe_frame
    from millctl.protocol import default_codec

    config = load_config(args.config).config
    codec, canopen = default_codec(), config.drives.backend == "cia402"
    controller_id = config.drives.controller_node_id
    furnace_channel = config.drives.furnace_bus.channel if config.drives.furnace_bus is not None else None

    def describe(frame: can.Message) -> str:
        # The furnace node's channel beside CiA 402 drives carries millbus frames (the service logs it in
        # the same file under its channel's name): read there with the DBC first, not as CANopen.
        on_canopen = canopen and (furnace_channel is None or frame.channel != furnace_channel)
        return describe_frame(frame, codec, canopen=on_canopen, controller_id=controller_id)

    return describe


def _entry(frame: can.Message, words: str) -> dict[str, Any]:
    """One frame for ``--json``: its time, channel, ID, data, direction and what it says."""
    return {"t_s": frame.timestamp, "channel": frame.channel, "id": frame.arbitration_id,
            "data": bytes(frame.data).hex(), "rx": frame.is_rx, "decoded": words}


def _line(frame: can.Message, words: str) -> str:
    return f"{frame.timestamp:17.6f}  {frame.arbitration_id:03X}  {bytes(frame.data).hex(' '):<23}  {words}"


class _Frames:
    """Where the frames go: a line each on stdout, or (``--json``) the one document's ``frames`` at the end."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.entries: list[dict[str, Any]] | None = [] if args.json else None
        self.out = stdout_console()
        self.shown = 0

    def add(self, frame: can.Message, words: str) -> None:
        self.shown += 1
        if self.entries is not None:
            self.entries.append(_entry(frame, words))
        else:
            self.out.print(_line(frame, words), markup=False, highlight=False, soft_wrap=True)

    def finish(self, **result: Any) -> None:
        if self.entries is not None:
            print_json(self.args, {**result, "frames_shown": self.shown, "frames": self.entries})


def _show(args: argparse.Namespace) -> int:
    import can

    path = Path(args.input)
    if not path.is_file():
        raise InvalidInputError(f"{path}: no such bus log (millctl writes them to records/bus/*.log)")
    describe, frames = _describer(args), _Frames(args)
    with can.LogReader(str(path)) as reader:
        for frame in reader:
            if frame.is_error_frame:
                continue
            frames.add(frame, describe(frame))
            if args.limit and frames.shown >= args.limit:
                break
    frames.finish(input=str(path))
    return int(ExitCode.OK)


def _monitor(args: argparse.Namespace) -> int:
    from millctl.config import load_config
    from millctl.protocol import open_bus

    if args.json and args.duration_s <= 0:
        # the document lists every frame heard: without an end, a busy or babbling bus grows it without bound
        raise InvalidInputError("bus monitor --json needs --duration-s S > 0: its one JSON document lists every "
                                "frame heard, printed when the monitor stops")
    describe, frames = _describer(args), _Frames(args)
    bus_config = load_config(args.config).config.bus
    bus = open_bus(bus_config)
    end = time.monotonic() + args.duration_s if args.duration_s > 0 else float("inf")
    try:
        while time.monotonic() < end:
            frame = bus.recv(timeout=min(0.2, max(end - time.monotonic(), 0.0)))
            if frame is None or frame.is_error_frame:
                continue
            frames.add(frame, describe(frame))
    except KeyboardInterrupt:
        stderr_console().print("monitor stopped", markup=False)
    finally:
        bus.shutdown()
    frames.finish(bus=f"{bus_config.interface}:{bus_config.channel}")
    return int(ExitCode.OK)


__all__ = ["add_view_commands"]
