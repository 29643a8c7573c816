"""``millctl bus load|frames|log convert``: bus load and frame table from the DBC; the bus log in every format."""

from __future__ import annotations

import argparse
from typing import Any

from millctl.cli.output import print_json, stderr_console, stdout_console
from millctl.errors import ExitCode


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number of bit/s") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{value} must be > 0")
    return value


def _nonnegative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value >= 0.0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{text} must be a finite number ≥ 0")
    return value


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``bus load`` and ``bus frames``."""
    parser = subparsers.add_parser("bus", help="the CAN protocol: bus load and frame table (config/millbus.dbc)")
    sub = parser.add_subparsers(dest="bus_command", metavar="ACTION", required=True)
    load = sub.add_parser(
        "load",
        help="worst-case bus load (bit stuffing included) of every frame and in total",
        description="Bus load from the DBC's cycle times, worst-case bit stuffing, target ≤ 15%%.",
    )
    load.add_argument("--bitrate", type=_positive_int, metavar="BIT_S", help="default: the config's bus bitrate")
    load.add_argument(
        "--event-rate-hz",
        type=_nonnegative_float,
        default=None,
        metavar="HZ",
        help="assumed worst-case rate of each event frame (default 10)",
    )
    load.add_argument("--json", action="store_true", help="machine-readable output")
    load.set_defaults(handler=_load)
    frames = sub.add_parser("frames", help="every frame and signal with its range, unit and rate")
    frames.add_argument("--json", action="store_true", help="machine-readable output")
    frames.add_argument("--markdown", action="store_true", help="the frame table as Markdown (docs/protocol.md)")
    frames.set_defaults(handler=_frames)
    log = sub.add_parser("log", help="the service's bus log (records/bus/*.log)")
    log_sub = log.add_subparsers(dest="log_command", metavar="ACTION", required=True)
    convert = log_sub.add_parser(
        "convert", help="convert a bus log to ASC, BLF, TRC, CSV or MF4 (by the output's suffix)",
        description="Convert a bus log with python-can's readers and writers (as python -m can.logconvert): "
        ".log (candump), .asc (Vector), .blf (Vector binary), .trc (PEAK), .csv, .mf4 (needs millctl[mf4]). "
        "Tx/Rx and the channel go across with every frame; an existing output is never overwritten.",
    )
    convert.add_argument("input", help="bus log to read")
    convert.add_argument("output", help="file to write; its suffix picks the format")
    convert.set_defaults(handler=_convert)


def _convert(args: argparse.Namespace) -> int:
    from pathlib import Path

    from millctl.protocol.buslog_convert import convert_log

    count = convert_log(Path(args.input), Path(args.output))
    stdout_console().print(f"{args.input} → {args.output}: {count} frames", markup=False)
    return int(ExitCode.OK)


def load_report(args: argparse.Namespace) -> dict[str, Any]:
    """The bus-load figures as plain data."""
    from millctl.config import load_config
    from millctl.protocol import default_codec
    from millctl.protocol.busload import DEFAULT_EVENT_RATE_HZ, TARGET_LOAD, bus_load

    bitrate = args.bitrate or load_config(args.config).config.bus.bitrate_bit_s
    event_rate = DEFAULT_EVENT_RATE_HZ if args.event_rate_hz is None else args.event_rate_hz
    load = bus_load(default_codec(), bitrate, event_rate)
    return {
        "bitrate_bit_s": load.bitrate_bit_s,
        "event_rate_hz": load.event_rate_hz,
        "periodic_load": load.periodic_load,
        "total_load": load.total_load,
        "target_load": TARGET_LOAD,
        "within_target": load.total_load <= TARGET_LOAD,
        "frames": [
            {
                "name": f.name,
                "id": f"0x{f.frame_id:03X}",
                "periodic": f.periodic,
                "rate_hz": f.rate_hz,
                "frame_bits": f.frame_bits,
                "bit_s": f.bit_rate_bit_s,
            }
            for f in load.frames
        ],
    }


def _load(args: argparse.Namespace) -> int:
    report = load_report(args)
    if args.json:
        print_json(args, report)
    else:
        from rich.table import Table

        table = Table(title=f"worst-case bus load at {report['bitrate_bit_s'] / 1000:g} kbit/s")
        for column in ("frame", "id", "kind", "rate Hz", "bits/frame", "bit/s", "load"):
            table.add_column(column, justify="left" if column in ("frame", "kind") else "right")
        for f in report["frames"]:
            table.add_row(
                f["name"],
                f["id"],
                "periodic" if f["periodic"] else "event (assumed)",
                f"{f['rate_hz']:g}",
                str(f["frame_bits"]),
                f"{f['bit_s']:.0f}",
                f"{f['bit_s'] / report['bitrate_bit_s']:.2%}",
            )
        console = stdout_console()
        console.print(table)
        console.print(
            f"periodic frames: {report['periodic_load']:.2%}; with every event frame at "
            f"{report['event_rate_hz']:g} Hz: {report['total_load']:.2%} (target ≤ {report['target_load']:.0%})",
            markup=False,
        )
    if not report["within_target"]:
        stderr_console().print(
            f"[yellow]warning:[/] total load {report['total_load']:.2%} exceeds the {report['target_load']:.0%} target"
        )
    return int(ExitCode.OK)


def frame_table() -> list[dict[str, Any]]:
    """Every frame of the DBC with its signals, as plain data."""
    from millctl.protocol import MESSAGE_TYPES, default_codec

    codec = default_codec()
    rows = []
    for kind in MESSAGE_TYPES:
        dbc = codec.database.get_message_by_name(kind.__name__)
        cycle = codec.cycle_time_s(kind)
        signals = [
            {
                "name": s.name,
                "start_bit": s.start,
                "length_bits": s.length,
                "signed": s.is_signed,
                "scale": s.scale,
                "offset": s.offset,
                "minimum": s.minimum,
                "maximum": s.maximum,
                "unit": s.unit or "",
                "choices": {int(k): str(v) for k, v in (s.choices or {}).items()},
                "comment": s.comment or "",
            }
            for s in dbc.signals
        ]
        rows.append(
            {
                "name": dbc.name,
                "id": f"0x{dbc.frame_id:03X}",
                "sender": ", ".join(dbc.senders),
                "cycle_ms": None if cycle is None else round(cycle * 1000),
                "e2e_data_id": None if codec.data_id(kind) is None else f"0x{codec.data_id(kind):04X}",
                "comment": dbc.comment or "",
                "signals": signals,
            }
        )
    return rows


def _frames(args: argparse.Namespace) -> int:
    rows = frame_table()
    if args.json:
        print_json(args, rows)
        return int(ExitCode.OK)
    lines = ["| ID | frame | sender | rate | E2E data ID | signals (unit, range) |", "|---|---|---|---|---|---|"]
    for row in rows:
        rate = "event" if row["cycle_ms"] is None else f"{row['cycle_ms']} ms ({1000 / row['cycle_ms']:g} Hz)"
        signals = "; ".join(
            f"`{s['name']}` ({s['unit'] or '-'}, {s['minimum']:g} … {s['maximum']:g}"
            + (f", ×{s['scale']:g}" if s["scale"] != 1 else "")
            + ")"
            for s in row["signals"]
        )
        lines.append(
            f"| {row['id']} | {row['name']} | {row['sender']} | {rate} | {row['e2e_data_id'] or '—'} | {signals} |"
        )
    if not args.markdown:
        lines = [line.replace("`", "") for line in lines]
    print("\n".join(lines))
    return int(ExitCode.OK)
