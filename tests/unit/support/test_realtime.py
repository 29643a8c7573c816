"""tests.support.realtime: the node keeps the real-time policy pytest was started with, the service runs below it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]

# A test process as .ci/test starts it: take over, then report which policy each thread and child runs at.
PROBE = """
import json, os, subprocess, sys, threading
from tests.support import realtime
kept = realtime.take_over()
child = "import os; print(os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)"
def policy_of(role):
    proc = realtime.popen([sys.executable, "-c", child], realtime=role, stdout=subprocess.PIPE)
    out, _ = proc.communicate(timeout=30)
    return [int(x) for x in out.split()]
def thread_policy():
    return [os.sched_getscheduler(0), os.sched_getparam(0).sched_priority]
seen = {}
thread = threading.Thread(target=lambda: seen.update(thread=thread_policy()))
thread.start(); thread.join()
instrument = threading.Thread(target=lambda: seen.update(instrument=thread_policy()))
realtime.start_thread(instrument, realtime="node"); instrument.join()
print(json.dumps({
    "kept": str(kept) if kept else None,
    "main": os.sched_getscheduler(0),
    "new_thread": seen["thread"],
    "realtime_thread": seen["instrument"],
    "node_child": policy_of("node"),
    "controller_child": policy_of("controller"),
    "normal_child": policy_of(None),
    "header": realtime.describe(),
}))
"""


def _run(prefix: list[str]) -> dict[str, object]:
    out = subprocess.run(
        [*prefix, sys.executable, "-c", PROBE], cwd=REPO, capture_output=True, text=True, timeout=60, check=True
    )
    result: dict[str, object] = json.loads(out.stdout)
    return result


def _chrt_permitted() -> bool:
    return subprocess.run(["chrt", "--rr", "1", "true"], capture_output=True, check=False).returncode == 0


def test_started_at_sched_rr_the_node_keeps_it_the_controller_runs_below_and_nothing_else_is_realtime() -> None:
    if not _chrt_permitted():  # no CAP_SYS_NICE here: the fallback is all there is to check
        test_started_at_the_normal_policy_everything_stays_normal()
        return
    seen = _run(["chrt", "--rr", "17"])
    assert seen["kept"] == "SCHED_RR priority 17"
    assert seen["main"] == os.SCHED_OTHER, "pytest's own thread must go back to the normal policy"
    assert seen["new_thread"] == [os.SCHED_OTHER, 0], "threads pytest starts afterwards must run at the normal policy"
    assert seen["node_child"] == [os.SCHED_RR, 17]
    assert seen["controller_child"] == [os.SCHED_RR, 7], "the controller runs NODE_ABOVE_CONTROLLER (10) below the node"
    assert seen["realtime_thread"] == [os.SCHED_RR, 17]
    assert seen["normal_child"] == [os.SCHED_OTHER, 0]
    assert "node runs at SCHED_RR priority 17, the service at SCHED_RR priority 7" in str(seen["header"])


def test_a_low_priority_start_still_leaves_the_controller_real_time_below_the_node() -> None:
    if not _chrt_permitted():
        return test_started_at_the_normal_policy_everything_stays_normal()
    seen = _run(["chrt", "--rr", "3"])
    assert seen["node_child"] == [os.SCHED_RR, 3]
    assert seen["controller_child"] == [os.SCHED_RR, 1], "the lowest real-time priority, never the normal policy"


def test_started_at_the_normal_policy_everything_stays_normal() -> None:
    seen = _run([])
    assert seen["kept"] is None
    assert seen["main"] == os.SCHED_OTHER
    assert seen["node_child"] == [os.SCHED_OTHER, 0]
    assert seen["controller_child"] == [os.SCHED_OTHER, 0]
    assert seen["realtime_thread"] == [os.SCHED_OTHER, 0]
    assert seen["normal_child"] == [os.SCHED_OTHER, 0]
    assert "normal scheduling policy" in str(seen["header"])
