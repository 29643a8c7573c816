"""``millctl report RUN``: the figures and the HTML page of one recipe run, from its run record."""

from __future__ import annotations

import argparse
from pathlib import Path

from millctl.cli.output import print_json, stderr_console, stdout_console
from millctl.errors import ExitCode


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``report``."""
    parser = subparsers.add_parser(
        "report",
        help="the report of a recipe run: speeds against the limit, margin, furnace, dose, events (PNG + HTML)",
        description="Draw a recipe run from its record: speeds against the enforced limit over time, the margin, "
        "the furnace temperature against its band, the dose accumulated, and every event and trip marked. Writes "
        "speeds.png, margin.png, furnace.png, dose.png, report.png (all four) and report.html (self-contained).",
    )
    parser.add_argument("run", metavar="RUN", help="the run record (runs/<run_id>.jsonl) or a run id")
    parser.add_argument("--out", metavar="DIR", type=Path,
                        help="where to write the report (default: ./report-<run_id>)")
    parser.add_argument("--json", action="store_true", help="machine-readable output (the summary and the files)")
    parser.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    from millctl.config import load_config
    from millctl.config.paths import service_paths
    from millctl.report import find_run, load_run, summary, write_report

    records_dir = service_paths(load_config(args.config)).records_dir
    run = load_run(find_run(args.run, records_dir))
    out = args.out or Path(f"report-{run.run_id}")
    written = write_report(run, out)
    if args.json:
        print_json(args, {"summary": summary(run), "files": [str(p) for p in written]})
        return int(ExitCode.OK)
    err = stderr_console()
    for path in written:
        err.print(f"wrote {path}", markup=False)
    stdout_console().print(str(out / "report.html"), markup=False)
    return int(ExitCode.OK)


__all__ = ["register"]
