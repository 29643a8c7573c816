"""Command line of the benchmarks: run, print, save JSON, plot, and regenerate docs/benchmarks.md.

Examples::

    python -m bench                                   # everything (a few minutes), report on stdout
    python -m bench --quick                           # smoke run, well under a minute (no hil tier)
    python -m bench --json results.json --write-docs  # full run, then docs/benchmarks.md and docs/img/
    python -m bench --from-json results.json --write-docs   # regenerate the document only

Progress goes to stderr, the report (markdown) to stdout.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bench import levels, node_budget, plots, report, safety_timing, work_precision
from bench.common import corrected_model, loadavg_now, machine
from bench.scenes import scene_set

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs" / "benchmarks.md"
PIECES = ("work-precision", "levels", "node", "safety")


def _progress(message: str) -> None:
    print(f"[bench] {message}", file=sys.stderr, flush=True)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser."""
    p = argparse.ArgumentParser(prog="python -m bench", description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="fewer scenes, sweep points and trials")
    p.add_argument(
        "--only",
        help=f"comma-separated subset of {', '.join(PIECES)} (default: all; with --quick all but safety, "
        "which runs the hil tier and takes about a minute on its own)",
    )
    p.add_argument("--json", metavar="FILE", help="write the results here (for comparison across commits)")
    p.add_argument("--plots", metavar="DIR", help="write work-precision.png here (needs the plot extra)")
    p.add_argument("--write-docs", action="store_true", help=f"write {DOCS.relative_to(ROOT)} and docs/img/")
    p.add_argument("--from-json", metavar="FILE", help="do not run: render a saved results file")
    p.add_argument("--lhs", type=int, help="number of Latin-hypercube scenes (default 4 quick, 32 full)")
    p.add_argument("--trials", type=int, help="hil trials (default 1 quick, 5 full)")
    return p


def run(args: argparse.Namespace, argv: Sequence[str]) -> dict[str, Any]:
    """Run the selected pieces and return the results dict."""
    if args.only is None:
        only = [p for p in PIECES if not (args.quick and p == "safety")]
        if args.quick:
            _progress("--quick skips the safety piece (hil tier, ~1 min); add --only safety to run it")
    else:
        only = [x.strip() for x in args.only.split(",") if x.strip()]
    unknown = set(only) - set(PIECES)
    if unknown:
        raise SystemExit(f"unknown --only piece(s) {sorted(unknown)}; choose from {', '.join(PIECES)}")
    start = time.perf_counter()
    res: dict[str, Any] = {
        "command": "python -m bench " + shlex.join(argv) if argv else "python -m bench",
        "quick": args.quick,
        "machine": machine(),
    }
    if "work-precision" in only:
        lhs = args.lhs if args.lhs is not None else (4 if args.quick else 32)
        scenes = scene_set(corrected_model(), lhs)
        _progress(f"work-precision: {len(scenes)} scenes")
        res["work_precision"] = work_precision.run(scenes, args.quick, _progress)
    if "levels" in only:
        _progress("levels of detail")
        res["levels"] = levels.run(args.quick)
    if "node" in only:
        _progress("node tick budget")
        res["node_budget"] = node_budget.run(args.quick)
    if "safety" in only:
        _progress("safety timing (hil tier) and bus load")
        res["safety_timing"] = safety_timing.run(args.quick, args.trials, _progress)
    res["duration_s"] = time.perf_counter() - start
    res["loadavg_end"] = loadavg_now()
    return res


def _plot(res: dict[str, Any], directory: Path) -> None:
    if "work_precision" not in res:
        return
    if reason := plots.matplotlib_missing():
        _progress(reason)
        return
    m = res["machine"]
    caption = (
        f"{res['command']} — {m['cpu_count']} CPUs, load {m['loadavg']}, Python {m['python']}, numpy {m['numpy']}; "
        "median over scenes"
    )
    path = plots.work_precision_plot(res["work_precision"]["summary"], directory / "work-precision.png", caption)
    _progress(f"wrote {path}")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    if args.from_json:
        res = json.loads(Path(args.from_json).read_text(encoding="utf-8"))
    else:
        res = run(args, argv)
        if args.json:
            Path(args.json).write_text(json.dumps(res, indent=1, default=str), encoding="utf-8")
            _progress(f"wrote {args.json}")
    if args.plots:
        _plot(res, Path(args.plots))
    if args.write_docs:
        if not args.plots:
            _plot(res, DOCS.parent / "img")
        DOCS.write_text(report.render(res), encoding="utf-8")
        _progress(f"wrote {DOCS}")
    print(report.render(res), end="")
    return 0
