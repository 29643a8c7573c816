"""``unshare -rm python -m tests.support.disk_full DIR``: a service whose records disk fills mid-recipe.

Runs inside a private user and mount namespace (nothing outside sees the
mount): mounts a small tmpfs on ``DIR/records``, starts ``millctl serve``
(embedded simulated node) with its records there, runs a recipe, fills the
tmpfs to the last byte, frees it again, stops the service, and prints one
JSON object of what it saw for ``tests/hil/service/test_records_disk.py`` to
judge.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from millctl.api import RecipeProgress
from millctl.client import Client
from millctl.records import read_records
from tests.support import realtime
from tests.support.pace import Deadline
from tests.support.service import start_service, write_config

T = TypeVar("T")

TMPFS_SIZE = "1m"
RECIPE = """\
[recipe]
name = "long hold"
[[steps]]
kind = "ramp"
rotary_rpm = 120.0
vibration_rpm = 400.0
[[steps]]
kind = "hold"
duration_s = 600
"""
CANDUMP = re.compile(r"^\([0-9.]+\) \S+ [0-9A-F]{3,8}#[0-9A-F]*( [RT])?$")


def _seen(client: Client) -> str:
    """What the service says now, for a failure message: controller state, trip cause, recipe progress."""
    try:
        status, progress = client.status(), client.recipe().progress
    except Exception as exc:
        return f"no answer ({type(exc).__name__}: {exc})"
    recipe = "no recipe"
    if progress is not None:
        recipe = f"recipe {progress.state} at step {progress.step} ({progress.reason!r})"
    return f"controller {status.state}, trip cause {status.trip_cause!r}, {recipe}"


def _until(condition: Callable[[], T | None], timeout_s: float, what: str, client: Client) -> T:
    """The first truthy answer of ``condition`` (errors count as not yet), within a wait that stretches with load."""
    deadline = Deadline(timeout_s)
    while not deadline.expired():
        with contextlib.suppress(Exception):
            found = condition()
            if found:
                return found
        time.sleep(0.1)
    raise SystemExit(f"timed out after {deadline.describe()} waiting for {what}; the service says: {_seen(client)}")


def _hold_step(client: Client) -> bool:
    """Whether the recipe is in its hold step; a recipe that stopped before it ends the scenario at once."""
    progress = client.recipe().progress
    if progress is not None and progress.state.final:
        raise SystemExit(f"the recipe stopped before its hold step: {_seen(client)}")
    return progress is not None and progress.step == 2


def _stopped(client: Client) -> RecipeProgress | None:
    """The recipe's progress once it has stopped (ABORTED or FAILED), else None."""
    progress = client.recipe().progress
    return progress if progress is not None and progress.state in ("ABORTED", "FAILED") else None


def _fill(directory: Path) -> Path:
    """Write a filler file until the disk is full (ENOSPC); return it."""
    filler = directory / "filler"
    block = b"\0" * 4096
    with open(filler, "wb", buffering=0) as handle, contextlib.suppress(OSError):
        while True:
            handle.write(block)
    return filler


def _records_intact(records: Path) -> dict[str, Any]:
    """Every JSON-lines record parses whole (a torn line only at a file's very end), every bus-log line is candump."""
    counts: dict[str, Any] = {"jsonl_records": 0, "bus_lines": 0, "bad_bus_lines": []}
    for path in sorted(records.rglob("*.jsonl")):
        counts["jsonl_records"] += len(list(read_records(path)))  # raises on a torn line inside
    for path in sorted(records.rglob("bus_*.log")):
        for line in path.read_text().splitlines():
            counts["bus_lines"] += 1
            if not CANDUMP.match(line):
                counts["bad_bus_lines"].append(line)
    return counts


def main(directory: Path) -> int:
    records = directory / "records"
    records.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={TMPFS_SIZE},mode=0750", "tmpfs", str(records)], check=True)
    write_config(directory)
    service = start_service(directory)
    seen: dict[str, Any] = {}
    try:
        with service.client("disk-full") as client, client.control():
            client.recipe_run_text("long-hold.toml", RECIPE)
            _until(lambda: _hold_step(client), 60.0, "the hold step", client)
            seen["seq_before"] = client.events().last_seq
            filler = _fill(records)
            warnings = _until(lambda: client.service().warnings, 30.0, "the records warning", client)
            seen["warnings"] = warnings
            progress = _until(lambda: _stopped(client), 60.0, "the recipe to stop", client)
            seen["recipe_state"], seen["recipe_reason"] = str(progress.state), progress.reason
            status = client.status()
            seen["state"], seen["trip_cause"] = str(status.state), status.trip_cause
            seen["node_state"], seen["node_faults"] = status.node_state, status.node_faults
            seen["links_stale"] = [name for name, link in status.link.items() if link.stale]
            events = client.events(after=seen["seq_before"], limit=2000).events
            seen["records_events"] = [e.message for e in events if e.kind == "records"]
            seen["set_while_full"] = client.set_speeds(60.0, 300.0).state  # still commanded, records or not
            filler.unlink()
            _until(lambda: not client.service().warnings, 30.0, "the warning to clear", client)
            seen["warnings_after_free"] = client.service().warnings
            client.stop()
    finally:
        seen["exit_code"] = service.stop()
    seen["records"] = _records_intact(records)
    seen["events_after"] = [r["kind"] for r in read_records(records / "events.jsonl")][-3:]
    print(json.dumps(seen, default=str))
    return 0


if __name__ == "__main__":
    realtime.take_over()  # started at the node's real-time priority (if any): its service gets the controller's
    os.chdir(Path(__file__).resolve().parents[2])
    sys.exit(main(Path(sys.argv[1])))
