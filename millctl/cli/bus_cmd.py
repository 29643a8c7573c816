"""``millctl bus load|frames|log convert``: bus load and frame table from the DBC; the bus log in every format."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from millctl.cli.output import print_json, stderr_console, stdout_console
from millctl.errors import ExitCode

if TYPE_CHECKING:
    from millctl.protocol.bus_check import BusCheckReport


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
    from millctl.cli.bus_view_cmd import add_view_commands

    add_view_commands(sub, log_sub)
    check = sub.add_parser(
        "check",
        help="is the configured bus up, at its bitrate, healthy, and does the node answer? (exit 0 yes, 3 no)",
        description="Opens the configured bus and listens (sends nothing): the interface, channel and bitrate; for "
        "socketcan the link's own bitrate, state and error counters (ip -details link); the adapter's condition "
        "and error frames; whether the node's NodeStatus (0x100) arrives within --listen-s. Exit 0: bus up and "
        "node present; 3: the bus cannot be opened, is bus-off, runs at another bitrate, or the node is silent; "
        "1: invalid configuration. With [drives] backend = \"cia402\": each drive's NMT state (its heartbeat), "
        "identity 0x1018 against its EDS, mode (0x6502) and the limits it holds, read by SDO, writing nothing "
        "(docs/deployment.md#standard-cia-402-drives); with a furnace node beside them ([drives.furnace_bus]), its "
        "channel and its NodeStatus too. docs/deployment.md#millctl-bus-check",
    )
    check.add_argument("--listen-s", type=_nonnegative_float, default=2.0, metavar="S",
                       help="how long to wait for the node's NodeStatus (default 2 s; it is sent every 50 ms)")
    check.add_argument("--json", action="store_true", help="machine-readable output")
    check.set_defaults(handler=_check)
    export = sub.add_parser(
        "export-c",
        help="write the C packers of millbus.dbc and the E2E header for a real node's firmware",
        description="cantools' C source generator writes millbus.h/millbus.c (a struct, pack/unpack and "
        "encode/decode per frame, C99, no allocation); millbus_e2e.h adds each frame's E2E data ID and the "
        "CRC-8/SAE-J1850 as millctl computes it. The rules a firmware must keep: docs/protocol.md"
        "#for-a-real-nodes-firmware. Existing files are never overwritten unless --force.",
    )
    export.add_argument("directory", help="folder to write into (made if missing)")
    export.add_argument("--node", choices=("Node", "Controller"),
                        help="only what this DBC node sends (pack) and receives (unpack); default: every frame")
    export.add_argument("--force", action="store_true", help="overwrite files of an earlier export")
    export.set_defaults(handler=_export_c)


def _convert(args: argparse.Namespace) -> int:
    from pathlib import Path

    from millctl.protocol.buslog_convert import convert_log

    count = convert_log(Path(args.input), Path(args.output))
    if args.json:
        print_json(args, {"input": args.input, "output": args.output, "frames": count})
        return int(ExitCode.OK)
    stdout_console().print(f"{args.input} → {args.output}: {count} frames", markup=False)
    return int(ExitCode.OK)


def _check(args: argparse.Namespace) -> int:
    from millctl.client import describe_bus_health
    from millctl.config import load_config
    from millctl.protocol import default_codec, open_bus
    from millctl.protocol.bus_check import check_bus

    config = load_config(args.config).config
    bus_config = config.bus
    if config.drives.backend == "cia402":
        return _check_cia402(args, config)
    bus = open_bus(bus_config)
    try:
        report = check_bus(bus_config, bus, default_codec(), args.listen_s)
    finally:
        bus.shutdown()
    if args.json:
        from millctl.cli.failures import EXIT_NAMES

        error = None if report.ok else {"code": EXIT_NAMES[ExitCode.BUS], "message": "; ".join(report.problems),
                                        "exit_code": int(ExitCode.BUS)}
        print_json(args, report.as_dict(), error)
    else:
        from millctl.api import BusHealthOut

        out = stdout_console()
        out.print(f"bus      {report.interface}:{report.channel}, configured {report.bitrate_bit_s} bit/s",
                  markup=False)
        if report.link is not None:
            link = report.link
            counters = "" if link["tx_error_counter"] is None else (
                f", TEC {link['tx_error_counter']} REC {link['rx_error_counter']}, bus-off {link['bus_off']}×"
            )
            out.print(f"link     {link['kind']} {link['operstate']}, state {link['state'] or '—'}, bitrate "
                      f"{link['bitrate_bit_s'] or '— (none on a vcan)'}{counters}", markup=False)
        elif report.link_note:
            out.print(f"link     {report.link_note}", markup=False)
        out.print(f"adapter  {describe_bus_health(BusHealthOut.model_validate(report.health))}", markup=False)
        node = (f"present: NodeStatus after {report.node_status_after_s:.2f} s, state {report.node_state}, first "
                f"fault {report.node_first_fault}") if report.node_present else "ABSENT"
        out.print(f"node     {node} ({report.frames} frames in {report.listened_s:.2f} s)", markup=False)
    for problem in report.problems:
        stderr_console().print(f"problem: {problem}", markup=False, style="bold red")
    return int(ExitCode.OK if report.ok else ExitCode.BUS)


def _check_furnace_channel(config: Any, listen_s: float) -> BusCheckReport | None:
    """The furnace node's own channel beside CiA 402 drives (``[drives.furnace_bus]``) as millbus checks it; or None."""
    from millctl.protocol import default_codec, open_bus
    from millctl.protocol.bus_check import check_bus

    furnace_bus = config.drives.furnace_bus
    if furnace_bus is None:
        return None
    bus = open_bus(furnace_bus)
    try:
        return check_bus(furnace_bus, bus, default_codec(), listen_s)
    finally:
        bus.shutdown()


def _check_cia402(args: argparse.Namespace, config: Any) -> int:
    """``bus check`` on CiA 402 drives: NMT state, identity 0x1018 against the EDS, mode, the limits they hold.

    With the millbus furnace node on a channel of its own, that channel and the node's NodeStatus are checked
    too; a problem there is named "furnace channel: …" and fails the check as a drive's does.
    """
    from millctl.drives.cia402.check import check_drives
    from millctl.protocol import open_bus

    bus = open_bus(config.bus)
    try:
        report = check_drives(config, bus, args.listen_s)
    finally:
        bus.shutdown()
    furnace = _check_furnace_channel(config, args.listen_s)
    problems = report.problems + ([f"furnace channel: {p}" for p in furnace.problems] if furnace else [])
    if args.json:
        from millctl.cli.failures import EXIT_NAMES

        error = None if not problems else {"code": EXIT_NAMES[ExitCode.BUS], "message": "; ".join(problems),
                                           "exit_code": int(ExitCode.BUS)}
        result = {**report.as_dict(), "furnace": furnace.as_dict() if furnace else None, "ok": not problems}
        print_json(args, result, error)
    else:
        out = stdout_console()
        bus_config = config.bus
        out.print(f"bus      {bus_config.interface}:{bus_config.channel}, configured {bus_config.bitrate_bit_s} bit/s, "
                  "CiA 402 drives", markup=False)
        for drive in report.drives:
            ident = drive.identity
            shown = (f"vendor 0x{ident['vendor_id']:08X} product 0x{ident['product_code']:08X} revision "
                     f"0x{ident['revision']:08X} serial {ident['serial']}, EDS "
                     f"{'matches' if drive.eds_match else 'DOES NOT MATCH'}") if ident else "identity unread"
            out.print(f"{drive.motor:<9}node {drive.node_id}, NMT {drive.nmt_state}, {shown}", markup=False)
            for where, values in drive.limits.items():
                held = values["drive_holds"]
                same = "" if held == values["millctl_writes"] else "  (millctl writes it before arming)"
                out.print(f"           {where}: holds {held if held is not None else '—'}, millctl writes "
                          f"{values['millctl_writes']}{same}", markup=False)
        if furnace is not None:
            node = (f"present: NodeStatus after {furnace.node_status_after_s:.2f} s, state {furnace.node_state}, "
                    f"first fault {furnace.node_first_fault}") if furnace.node_present else "ABSENT"
            out.print(f"furnace  millbus node on {furnace.interface}:{furnace.channel}: {node} ({furnace.frames} "
                      f"frames in {furnace.listened_s:.2f} s)", markup=False)
    for problem in problems:
        stderr_console().print(f"problem: {problem}", markup=False, style="bold red")
    return int(ExitCode.BUS if problems else ExitCode.OK)


def _export_c(args: argparse.Namespace) -> int:
    from pathlib import Path

    from millctl.protocol import default_codec
    from millctl.protocol.export_c import export_c

    paths = export_c(default_codec(), Path(args.directory), node=args.node, overwrite=args.force)
    if args.json:
        print_json(args, {"written": [str(p) for p in paths]})
        return int(ExitCode.OK)
    console = stdout_console()
    for path in paths:
        console.print(f"wrote {path}", markup=False)
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
