"""A recipe outlives its service: SIGKILL (or stop) mid-recipe, restart, the run is offered, resumed, and completes."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from millctl.client import ServiceRefused, read_recipe_text
from millctl.recipes.history import read_history
from millctl.records import read_records
from tests.hil.service.test_recipe_cli import fast_mill, recipe
from tests.support.pace import stretched
from tests.support.service import REPO, Service, private_dir, run_millctl, start_service, wait_for

pytestmark = pytest.mark.timeout(300)  # a safety net against a hang: each test lives through two service starts


def millctl_no_tty(config: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """``millctl`` with stdin from /dev/null: no terminal to ask the operator on."""
    return subprocess.run([sys.executable, "-m", "millctl", "--config", str(config), *args], cwd=REPO,
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=stretched(60.0),
                          check=False)


def start_in_the_hold(directory: Path, hold_s: float) -> tuple[Service, str, Path]:
    """A service running the short recipe, a couple of seconds into its hold step."""
    running = start_service(directory)
    with running.client() as client, client.control():
        client.recipe_run(recipe(directory, hold_s=hold_s))
        wait_for(lambda: (p := client.recipe().progress) is not None and p.step == 2
                 and (p.step_elapsed_s or 0.0) >= 2.5, 60, "2.5 s into the hold step")
        progress = client.recipe().progress
        assert progress is not None
    return running, progress.run_id, Path(progress.record)


def test_a_run_killed_mid_recipe_is_offered_after_the_restart_and_resumed_to_done() -> None:
    with private_dir() as directory:
        fast_mill(directory)
        first, run_id, record = start_in_the_hold(directory, hold_s=10.0)
        assert first.stop(signal.SIGKILL) == -signal.SIGKILL
        done_before = read_history(record).step_elapsed_s
        assert 1.0 <= done_before <= 4.0

        running = start_service(directory)  # the node's watchdog stopped the mill; a new service, a new node
        try:
            with running.client() as client:
                described = client.service()
                assert described.unfinished_runs == [run_id]
                assert any(f"millctl recipe resume {run_id}" in w for w in described.warnings)
                assert any(e.message.startswith(f"unfinished run {run_id} (short, step 2/2)")
                           for e in client.events().events)  # found at start, in the journal
            listed = run_millctl(running.config, "recipe", "list", "--json")
            assert listed.returncode == 0, listed.stderr
            [offered] = json.loads(listed.stdout)["result"]["runs"]
            assert offered["run_id"] == run_id and offered["state"] == "INTERRUPTED" and offered["step"] == 2
            assert offered["step_elapsed_s"] == done_before and "crash, a kill or a power loss" in offered["reason"]

            # no operator, no resume: nothing moves
            unconfirmed = millctl_no_tty(running.config, "recipe", "resume", run_id)
            assert unconfirmed.returncode == 2 and "confirm with --yes" in unconfirmed.stderr
            assert "then step 2 (hold) continues with" in unconfirmed.stderr
            with running.client() as client, client.control():
                # a changed recipe is refused
                changed = read_recipe_text(recipe(directory, hold_s=11.0))[1]
                with pytest.raises(ServiceRefused, match="the recipe changed"):
                    client.recipe_resume_run(run_id, confirm=True, text=changed)
                assert client.status().setpoint_rotary_rpm == 0.0 and client.recipe().progress is None

            resumed = millctl_no_tty(running.config, "recipe", "resume", run_id, "--yes", "--detach")
            assert resumed.returncode == 0, resumed.stderr
            with running.client() as client, client.control():
                # a second resume while it runs; `--detach` returns once the service took the run, which may
                # still be STARTING (restoring its step) when this one arrives (seen under load)
                with pytest.raises(ServiceRefused, match=f"run {run_id} is (STARTING|RUNNING) in this service"):
                    client.recipe_resume_run(run_id, confirm=True)
                wait_for(lambda: (p := client.recipe().progress) is not None and p.state == "DONE", 90,
                         "the resumed run to end DONE")
                final = client.recipe().progress
                assert final is not None and final.run_id == run_id and final.resumed and final.gap_s > 0.0
                assert client.service().unfinished_runs == []
                with pytest.raises(ServiceRefused, match="ended DONE"):
                    client.recipe_resume_run(run_id, confirm=True)  # a finished run
        finally:
            running.stop()
        records = list(read_records(record))
        events = [r["event"] for r in records if r["event"] != "sample"]
        assert events.count("start") == 1 and events[-1] == "end" and records[-1]["status"] == "DONE"
        [gap] = [r for r in records if r["event"] == "gap"]
        assert gap["step"] == 2 and gap["credited_s"] == done_before and gap["end_t"] > gap["start_t"]
        assert gap["reason"].startswith("the service ended without closing the run")
        assert events.index("gap") < events.index("restore") < events.index("restored") < events.index("end")


def test_a_service_stop_interrupts_the_run_and_an_operator_can_close_it() -> None:
    with private_dir() as directory:
        fast_mill(directory)
        first, run_id, record = start_in_the_hold(directory, hold_s=60.0)
        assert first.stop(signal.SIGTERM) == 0
        history = read_history(record)
        assert history.ended is None and history.interrupt_reason  # a stop is not an abort: resumable
        running = start_service(directory)
        try:
            listed = run_millctl(running.config, "recipe", "list")
            assert listed.returncode == 0 and f"millctl recipe resume {run_id}" in listed.stdout
            assert "interrupted: " in listed.stdout
            closed = run_millctl(running.config, "recipe", "abort", run_id)
            assert closed.returncode == 0, closed.stderr
            with running.client() as client, client.control():
                assert client.service().unfinished_runs == []
                with pytest.raises(ServiceRefused, match="ended ABORTED"):
                    client.recipe_resume_run(run_id, confirm=True)
            unknown = millctl_no_tty(running.config, "recipe", "resume", "20990101T000000Z-000000", "--yes")
            assert unknown.returncode == 1 and "no record" in unknown.stderr
        finally:
            running.stop()
        assert read_history(record).ended == "ABORTED"
