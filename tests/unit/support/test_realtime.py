"""tests.support.realtime: the service and node keep the real-time policy pytest was started with; pytest does not."""

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
def policy_of(realtime_child):
    proc = realtime.popen([sys.executable, "-c", child], realtime=realtime_child, stdout=subprocess.PIPE)
    out, _ = proc.communicate(timeout=30)
    return [int(x) for x in out.split()]
seen = {}
thread = threading.Thread(target=lambda: seen.update(thread=os.sched_getscheduler(0)))
thread.start(); thread.join()
instrument = threading.Thread(target=lambda: seen.update(instrument=os.sched_getscheduler(0)))
realtime.start_thread(instrument, realtime=True); instrument.join()
print(json.dumps({
    "kept": str(kept) if kept else None,
    "main": os.sched_getscheduler(0),
    "new_thread": seen["thread"],
    "realtime_thread": seen["instrument"],
    "realtime_child": policy_of(True),
    "normal_child": policy_of(False),
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


def test_started_at_sched_rr_only_the_realtime_children_keep_it() -> None:
    if not _chrt_permitted():  # no CAP_SYS_NICE here: the fallback is all there is to check
        test_started_at_the_normal_policy_everything_stays_normal()
        return
    seen = _run(["chrt", "--rr", "7"])
    assert seen["kept"] == "SCHED_RR priority 7"
    assert seen["main"] == os.SCHED_OTHER, "pytest's own thread must go back to the normal policy"
    assert seen["new_thread"] == os.SCHED_OTHER, "threads pytest starts afterwards must run at the normal policy"
    assert seen["realtime_child"] == [os.SCHED_RR, 7]
    assert seen["realtime_thread"] == os.SCHED_RR
    assert seen["normal_child"] == [os.SCHED_OTHER, 0]
    assert "SCHED_RR priority 7 (real-time)" in str(seen["header"])


def test_started_at_the_normal_policy_everything_stays_normal() -> None:
    seen = _run([])
    assert seen["kept"] is None
    assert seen["main"] == os.SCHED_OTHER
    assert seen["realtime_child"] == [os.SCHED_OTHER, 0]
    assert seen["realtime_thread"] == os.SCHED_OTHER
    assert seen["normal_child"] == [os.SCHED_OTHER, 0]
    assert "normal scheduling policy" in str(seen["header"])
