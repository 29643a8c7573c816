"""``millctl recipe run`` through the service: summary, embedded start, Ctrl+C, and records after SIGKILL."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

from millctl.records import read_records
from tests.support.pace import stretched
from tests.support.service import REPO, Service, private_dir, run_millctl, start_service, wait_for, write_config

SHORT = """
[recipe]
name = "short"
[[steps]]
kind = "ramp"
rotary_rpm = 60.0
vibration_rpm = 300.0
[[steps]]
kind = "hold"
duration_s = {hold_s}
"""


def fast_mill(directory: Path) -> Path:
    """A config whose drives accelerate 10× faster (same envelope): the runs take seconds, not tens of seconds."""
    config = write_config(directory)
    text = config.read_text()
    for old, new in (("max_accel_rpm_s = 40.0", "max_accel_rpm_s = 400.0"),
                     ("max_accel_rpm_s = 120.0", "max_accel_rpm_s = 1200.0")):
        assert old in text, old
        text = text.replace(old, new)
    config.write_text(text)
    return config


def recipe(directory: Path, hold_s: float = 1.0) -> Path:
    path = directory / "short.toml"
    path.write_text(SHORT.format(hold_s=hold_s))
    return path


def test_run_prints_a_summary_and_writes_a_complete_record(service: Service) -> None:
    result = run_millctl(service.config, "recipe", "run", str(recipe(service.config.parent)), "--json", timeout_s=90)
    assert result.returncode == 0, result.stderr
    import json

    summary = json.loads(result.stdout)["result"]
    assert summary["state"] == "DONE" and summary["steps"] == 2
    records = list(read_records(summary["record"]))
    assert records[0]["event"] == "start" and records[-1]["event"] == "end" and records[-1]["status"] == "DONE"
    assert records[0]["recipe_file"].endswith("short.toml") and len(records[0]["config_sha256"]) == 64


def test_run_starts_the_embedded_service_when_none_runs_and_stops_it_after() -> None:
    with private_dir() as directory:
        config = fast_mill(directory)
        result = run_millctl(config, "recipe", "run", str(recipe(directory)), timeout_s=120, realtime="controller")
        assert result.returncode == 0, result.stderr
        assert "starting a SIMULATED mill" in result.stderr
        assert "recipe short: DONE" in result.stdout
        assert not (directory / "mill.sock").exists()


def test_a_bad_recipe_is_refused_before_anything_moves(service: Service) -> None:
    bad = service.config.parent / "bad.toml"
    bad.write_text('[recipe]\nname = "bad"\n[[steps]]\nkind = "ramp"\nrotary_rpm = 250\nvibration_rpm = 800\n')
    result = run_millctl(service.config, "recipe", "run", str(bad))
    assert result.returncode == 2  # refused, as every refusal
    assert "step 1 at t = 0.0 s: ω_r = 250.0 rpm exceeds the limit" in result.stderr
    with service.client() as client:
        assert client.status().setpoint_rotary_rpm == 0.0


def test_ctrl_c_once_pauses_twice_aborts_with_exit_2() -> None:
    with private_dir() as directory:
        fast_mill(directory)
        running = start_service(directory)
        try:
            proc = subprocess.Popen(
                [sys.executable, "-m", "millctl", "--config", str(running.config), "recipe", "run",
                 str(recipe(directory, hold_s=120.0))],
                cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            )
            with running.client() as client:
                wait_for(lambda: (p := client.recipe().progress) is not None and p.step == 2, 60, "the hold step")
                proc.send_signal(signal.SIGINT)
                wait_for(lambda: (p := client.recipe().progress) is not None and p.state == "PAUSED", 10, "the pause")
                proc.send_signal(signal.SIGINT)
                out, err = proc.communicate(timeout=stretched(60.0))
                assert proc.returncode == 2, err
                progress = client.recipe().progress
                assert progress is not None and progress.state == "ABORTED"
                assert "ABORTED" in out
        finally:
            if proc.poll() is None:
                proc.kill()
            running.stop()


def test_run_record_is_complete_up_to_a_sigkill() -> None:
    with private_dir() as directory:
        fast_mill(directory)
        running = start_service(directory)
        try:
            result = run_millctl(running.config, "recipe", "run", "--detach", str(recipe(directory, hold_s=120.0)))
            assert result.returncode == 0, result.stderr
            with running.client() as client:
                wait_for(lambda: (p := client.recipe().progress) is not None and p.step == 2, 60, "the hold step")
                progress = client.recipe().progress
                assert progress is not None
                path = progress.record
        finally:
            running.stop(signal.SIGKILL)
        records = list(read_records(path))  # every line parses
        events = [r["event"] for r in records if r["event"] != "sample"]  # samples come between the steps' events
        assert events[:2] == ["start", "step_start"] and "step_end" in events
        assert events[-1] == "step_start" and records[-1]["step"] == 2
        assert "end" not in events
