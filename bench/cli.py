"""Command line of the benchmarks: run, print, save JSON, plot, and regenerate docs/benchmarks.md.

Examples::

    python -m bench                                   # everything (a few minutes), report on stdout
    python -m bench --quick                           # smoke run, well under a minute (no hil tier)
    python -m bench --json results.json --write-docs  # full run, then docs/benchmarks.md and docs/img/
    python -m bench --from-json results.json --write-docs   # regenerate the document only

Progress goes to stderr, the report (markdown) to stdout, issue 40's targets (measured / target / met)
at its end. ``--write-docs`` refuses a run made on a loaded host (:mod:`bench.targets`, exit code 1):
the host's load is recorded at the start of every piece and printed under every table.
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

from bench import compiled, levels, node_budget, plots, report, safety_timing, study, targets, work_precision
from bench.common import corrected_model, loadavg_now, machine
from bench.options import PIECES, add_options
from bench.scenes import scene_set

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs" / "benchmarks.md"


def _progress(message: str) -> None:
    print(f"[bench] {message}", file=sys.stderr, flush=True)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser."""
    parser = argparse.ArgumentParser(prog="python -m bench", description=__doc__.splitlines()[0])
    add_options(parser)
    return parser


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
        "loads": {},
    }

    def starting(piece: str) -> bool:
        if piece in only:
            res["loads"][piece] = targets.load_now()
        return piece in only

    if starting("work-precision"):
        lhs = args.lhs if args.lhs is not None else (4 if args.quick else 32)
        scenes = scene_set(corrected_model(), lhs)
        _progress(f"work-precision: {len(scenes)} scenes")
        res["work_precision"] = work_precision.run(scenes, args.quick, _progress)
    if starting("compiled"):
        res["compiled"] = compiled.run(args.quick, _progress)
    if starting("levels"):
        _progress("levels of detail")
        res["levels"] = levels.run(args.quick)
    if starting("node"):
        _progress("node tick budget")
        res["node_budget"] = node_budget.run(args.quick)
    if starting("safety"):
        _progress("safety timing (hil tier) and bus load")
        res["safety_timing"] = safety_timing.run(args.quick, args.trials, _progress)
    if starting("study"):
        _progress("design-study throughput (100 x 100 map; --quick 10 x 10)")
        res["study"] = study.run(args.quick, _progress)
    res["duration_s"] = time.perf_counter() - start
    res.update(report.issue17_figures(res))
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
    return run_parsed(build_parser().parse_args(argv), argv)


def run_parsed(args: argparse.Namespace, argv: Sequence[str]) -> int:
    """Run with parsed options (``argv`` only labels the results); also the handler of ``millctl bench``."""
    if args.from_json:
        res = json.loads(Path(args.from_json).read_text(encoding="utf-8"))
    else:
        res = run(args, argv)
        if args.json:
            Path(args.json).write_text(json.dumps(res, indent=1, default=str), encoding="utf-8")
            _progress(f"wrote {args.json}")
    if args.plots:
        _plot(res, Path(args.plots))
    if args.write_docs and (why := targets.loaded(res)):
        print(report.render(res), end="")
        _progress(f"not writing {DOCS}: {why}")
        return 1
    if args.write_docs:
        if not args.plots:
            _plot(res, DOCS.parent / "img")
        DOCS.write_text(report.render(res), encoding="utf-8")
        _progress(f"wrote {DOCS}")
    print(report.render(res), end="")
    return 0
