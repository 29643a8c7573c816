"""Mill at a point with the bluesky RunEngine, store the documents with a standard callback, plot the readings.

    python docs/examples/bluesky_mill_at.py [--socket PATH] [--rot-rpm 150] [--vib-rpm 800] [--seconds 10] \
        [--out DIR]

Needs a running ``millctl serve`` (``millctl serve --sim`` for the simulated mill) and the extra
``pip install 'millctl[bluesky]'``. Writes ``DIR/<run uid>.jsonl`` (bluesky's ``JSONLinesWriter``: every document
of the run, one a line) and ``DIR/<run uid>.png`` (the measured speeds and the margin to the envelope, read back
from that file). The start document names the mill, its configuration's sha256 and the service's event number at
the start: join it to ``millctl events`` / ``<records_dir>/events.jsonl`` (docs/bluesky.md#data).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from bluesky import RunEngine
from bluesky.callbacks.json_writer import JSONLinesWriter
from bluesky.run_engine import call_in_bluesky_event_loop
from ophyd_async.plan_stubs import ensure_connected

from millctl.bluesky import Mill, SuspendWhenMillNotReady
from millctl.bluesky.plans import mill_at


def plot(documents: list[dict[str, Any]], out: Path) -> None:
    """The run's readings, from its stored documents: ω_r and ω_v measured, and the margin to the limit."""
    start = next(d["doc"] for d in documents if d["name"] == "start")
    events = [d["doc"] for d in documents if d["name"] == "event"]
    t0 = start["time"]
    t = [e["time"] - t0 for e in events]
    fig, (speeds, margin) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
    speeds.plot(t, [e["data"]["mill-rotary"] for e in events], "o-", label="ω_r measured (rpm)")
    speeds.plot(t, [e["data"]["mill-vibration"] for e in events], "s-", label="ω_v measured (rpm)")
    speeds.legend()
    speeds.set_title(f"{start['plan_name']} on {start['millctl_mill']} ({start['millctl_law']})")
    margin.plot(t, [e["data"]["mill-margin_rpm"] for e in events], "o-", color="tab:green")
    margin.set_ylabel("margin to the limit (rpm)")
    margin.set_xlabel("time since the start (s)")
    fig.tight_layout()
    fig.savefig(out)


def main(argv: list[str] | None = None) -> int:
    """Run the plan, store its documents, plot them; 0 when the run succeeded."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--socket", help="the service socket (default: the config's, as every millctl client)")
    parser.add_argument("--rot-rpm", type=float, default=150.0)
    parser.add_argument("--vib-rpm", type=float, default=800.0)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--out", type=Path, default=Path("bluesky-run"))
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)

    RE = RunEngine(call_returns_result=True)
    writer = JSONLinesWriter(str(args.out))
    RE.subscribe(writer)
    mill = Mill(args.socket, name="mill", client_name="bluesky-example")
    RE(ensure_connected(mill))
    RE.install_suspender(SuspendWhenMillNotReady(mill))
    try:
        result = RE(mill_at(mill, args.rot_rpm, args.vib_rpm, duration_s=args.seconds))
    finally:
        call_in_bluesky_event_loop(mill.close())
    stored = args.out / str(writer.filename)
    documents = [json.loads(line) for line in stored.read_text().splitlines()]
    plot(documents, stored.with_suffix(".png"))
    sys.stderr.write(f"run {result.run_start_uids[0]}: {result.exit_status}; documents {stored}, "
                     f"plot {stored.with_suffix('.png')}\n")
    return 0 if result.exit_status == "success" else 2


if __name__ == "__main__":
    sys.exit(main())
