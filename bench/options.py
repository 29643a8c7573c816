"""The benchmark's command-line options, light to import (``millctl bench`` registers them for its --help)."""

from __future__ import annotations

import argparse

PIECES = ("work-precision", "compiled", "levels", "node", "safety", "study")


def add_options(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``python -m bench`` to ``parser``."""
    parser.add_argument("--quick", action="store_true", help="fewer scenes, sweep points and trials")
    parser.add_argument(
        "--only",
        help=f"comma-separated subset of {', '.join(PIECES)} (default: all; with --quick all but safety, "
        "which runs the hil tier and takes about a minute on its own)",
    )
    parser.add_argument("--json", metavar="FILE", help="write the results here (for comparison across commits)")
    parser.add_argument("--plots", metavar="DIR", help="write work-precision.png here (needs the plot extra)")
    parser.add_argument("--write-docs", action="store_true", help="write docs/benchmarks.md and docs/img/")
    parser.add_argument("--from-json", metavar="FILE", help="do not run: render a saved results file")
    parser.add_argument("--lhs", type=int, help="number of Latin-hypercube scenes (default 4 quick, 32 full)")
    parser.add_argument("--trials", type=int, help="hil trials (default 1 quick, 5 full)")
