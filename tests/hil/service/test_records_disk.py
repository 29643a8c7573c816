"""A full records disk (a 1 MiB tmpfs in a private mount namespace) keeps the mill controlled and says so (SAFETY 23).

The scenario runs in ``tests.support.disk_full`` under ``unshare -rm`` (no
privilege needed, nothing outside sees the mount); this test judges what it
printed. It is started at the hil tiers' real-time policy, where there is one
(tests/support/realtime.py), and keeps it for its service only, as every other
hil service test does: the recipe's hold step must not depend on unrelated load.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest

from tests.support.pace import stretched
from tests.support.realtime import popen as realtime_popen
from tests.support.service import REPO, private_dir


def _unshare_works() -> bool:
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(["unshare", "-rm", "true"], capture_output=True, check=False)
    return probe.returncode == 0


@pytest.mark.skipif(not _unshare_works(), reason="needs unprivileged user and mount namespaces (unshare -rm)")
def test_a_full_records_disk_keeps_the_mill_controlled_says_so_and_damages_nothing() -> None:
    with private_dir() as directory:
        argv = ["unshare", "-rm", sys.executable, "-m", "tests.support.disk_full", str(directory)]
        # At the node's priority: the scenario's own take_over then gives its service the controller's.
        scenario = realtime_popen(argv, realtime="node", cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            out, err = scenario.communicate(timeout=stretched(300.0))
        finally:
            if scenario.poll() is None:
                scenario.kill()
                scenario.communicate()
        stdout, stderr = out.decode(errors="replace"), err.decode(errors="replace")
        assert scenario.returncode == 0, stdout[-3000:] + stderr[-3000:]
    seen = json.loads(stdout.strip().splitlines()[-1])
    # visible: a status warning and an event, naming the cause
    assert seen["warnings"] and "No space left on device" in seen["warnings"][0]
    assert "the mill is controlled as before" in seen["warnings"][0]
    assert seen["records_events"] and "No space left on device" in seen["records_events"][0]
    # the running recipe stopped in a controlled way, the mill still commanded, no trip, no watchdog
    assert seen["recipe_state"] == "ABORTED" and "records cannot be written" in seen["recipe_reason"]
    assert seen["state"] == "ARMED" and seen["trip_cause"] == "" and seen["node_faults"] == []
    assert seen["links_stale"] == []
    assert seen["set_while_full"] == "RUNNING"
    # the warning clears once there is room, and the service stops cleanly
    assert seen["warnings_after_free"] == [] and seen["exit_code"] == 0
    # nothing already written is damaged: every record parses, every bus-log line is whole
    assert seen["records"]["jsonl_records"] > 0 and seen["records"]["bus_lines"] > 0
    assert seen["records"]["bad_bus_lines"] == []
    assert seen["events_after"][-1] == "service"
