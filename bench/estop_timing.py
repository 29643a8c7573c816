"""E-stop reaction under load: a node babbling at 1000 Hz, and a flood on 0x001 at the bus's maximum rate.

Runs the adversary scenarios of ``tests/hil/test_adversary.py`` that measure
them (on udp_multicast, inside ``tests/hil/in_netns``, at the hil tiers' priority:
``tests/hil/rt``) ``trials`` times
through :func:`bench.safety_timing.hil_trials`, and prints median, p99 and
max of the reaction (E-stop frame sent → the node's NodeStatus FAULT/ESTOP
on the bus) against its bound, the ``node_reports_s`` of
``tests/hil/scenario_support.Bounds``: one node tick, one NodeStatus period
and the scheduling allowance (docs/safety.md, "Bus input").

    .venv/bin/python -m bench.estop_timing --trials 5
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from typing import Any

from bench.safety_timing import ROOT, hil_trials

SUITE = ROOT / "tests" / "hil" / "test_adversary.py"
KEYWORD = "(estop_under_a_babbling_node and 1000) or estop_inside_a_flood"
"""pytest -k terms: the 1000 Hz babble and the flood scenario."""
WHAT = {
    "estop_under_babble_1000hz": "E-stop → NodeStatus FAULT/ESTOP, node babbling 1000 frames/s on 0x001",
    "estop_in_flood_0x001": "E-stop → NodeStatus FAULT/ESTOP, flood on 0x001 at 3704 frames/s (500 kbit/s)",
}


def run(trials: int) -> dict[str, Any]:
    """The scenarios ``trials`` times; per record: n, median, p99, max, bound, and how many were over it."""
    result = hil_trials(trials, KEYWORD, progress=lambda line: print(line, file=sys.stderr), suite=SUITE)
    for name, stats in result.get("stats", {}).items():
        stats["what"] = WHAT.get(name, name)
    return result


def table(result: dict[str, Any]) -> str:
    """The figures as a markdown table (ms)."""
    if "skipped" in result:
        return f"skipped: {result['skipped']}"
    rows = [
        "| reaction | n | median ms | p99 ms | max ms | bound ms | over bound |",
        "|---|---|---|---|---|---|---|",
    ]
    for stats in result["stats"].values():
        rows.append(
            f"| {stats['what']} | {stats['n']} | {stats['median_s'] * 1e3:.1f} | {stats['p99_s'] * 1e3:.1f} | "
            f"{stats['max_s'] * 1e3:.1f} | {stats['bound_s'] * 1e3:.0f} | {stats['over_bound']} |"
        )
    failed = [line for outcome in result["outcomes"] for line in outcome["failed"]]
    return "\n".join([*rows, "", f"command: {result['command']}", *(f"failed: {line}" for line in failed)])


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: run, print the table (and the JSON with ``--json``)."""
    parser = argparse.ArgumentParser(prog="python -m bench.estop_timing", description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=5, help="pytest runs of the scenarios (default 5)")
    parser.add_argument("--json", help="also write the full result (every record) to this file")
    args = parser.parse_args(argv)
    result = run(args.trials)
    print(table(result))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as out:
            json.dump(result, out, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
