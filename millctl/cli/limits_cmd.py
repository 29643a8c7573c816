"""``millctl limits``: ω_r,max against ω_v for every detachment law, with regime flags.

The parser is all this module loads; the table, its printing and its plot (:mod:`millctl.cli.limits_view`, with
numpy, the physics and the configuration models) load when the command runs, so that ``millctl --help`` and
the other commands start without them.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from millctl.cli.args import LazyChoices, nonnegative_float
from millctl.cli.output import print_json, stderr_console
from millctl.errors import ExitCode


def _law_names() -> list[str]:
    from millctl.config import LimitLaw

    return [law.value for law in LimitLaw]


def _cam_names() -> list[str]:
    from millctl.config import CamShape

    return [cam.value for cam in CamShape]


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``limits``."""
    parser = subparsers.add_parser(
        "limits",
        help="table (and plot) of the maximum rotary speed against vibration speed",
        description="ω_r,max against ω_v for every detachment law, the enforced envelope and the regime flags.",
    )
    parser.add_argument(
        "--vib-rpm",
        type=nonnegative_float,
        nargs="+",
        metavar="RPM",
        help="vibration speeds (default: 0 to the drive's maximum in 100 rpm steps)",
    )
    parser.add_argument(
        "--law",
        choices=LazyChoices(_law_names),
        metavar="LAW",
        help="law for the envelope column: %(choices)s (default: the configured interlock law)",
    )
    parser.add_argument(
        "--cam",
        choices=LazyChoices(_cam_names),
        metavar="CAM",
        help="cam shape: %(choices)s (default: the configured one); with it, the two cams compared at the same "
        "speeds",
    )
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.add_argument(
        "--plot",
        metavar="FILE.png",
        type=Path,
        nargs="?",
        const=Path("limits.png"),
        help="draw which rotary speed is safe (the envelope, every law, the operating points) and the admissible "
        "cam phase, the paper's Fig. 5 and Fig. 6 counterparts (default file: limits.png; needs the plot extra)",
    )
    parser.add_argument(
        "--recipe",
        metavar="RECIPE.toml",
        help="with --plot: draw the path the planner drives through this recipe's steps, their targets marked",
    )
    parser.add_argument(
        "--at",
        type=nonnegative_float,
        nargs=2,
        action="append",
        metavar=("VIB_RPM", "ROT_RPM"),
        help="with --plot: mark a planned operating point ω_v ω_r (rpm); repeat for more",
    )
    parser.add_argument(
        "--live",
        action="store_true",
        help="with --plot: mark the measured speeds and the target of the running service",
    )
    parser.add_argument("--socket", metavar="PATH", help="with --live: service socket (default: from the config)")
    parser.set_defaults(handler=_run)


def limits_table(args: argparse.Namespace) -> dict[str, Any]:
    """Compute the limits table as plain data (:func:`millctl.cli.limits_view.limits_table`)."""
    from millctl.cli import limits_view

    return limits_view.limits_table(args)


def _run(args: argparse.Namespace) -> int:
    from millctl.cli import limits_view

    table = limits_table(args)
    if args.cam:
        table["cams"] = limits_view.cams_table(args, table)
    if args.plot:
        limits_view.plot_limits(args.plot, table, args)
    if args.json:
        print_json(args, table)
    else:
        limits_view.print_table(table)
        if "cams" in table:
            limits_view.print_cams(table)
    if table["regime"] is not None:
        stderr_console().print(f"[yellow]warning:[/] {table['regime']['message']}", highlight=False)
    return int(ExitCode.OK)


__all__ = ["limits_table", "register"]
