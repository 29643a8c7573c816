"""Interrupting ``millctl study`` in real processes: Ctrl+C, SIGINT to the parent, a killed parent, two runs.

The study is sized to run for minutes (level-c points, two local workers); each test acts once some
points are saved and then waits (load-stretched, tests/support/pace.py) for what must follow. None
times the stop: "within 2 s" is measured by hand (docs/studies.md); here the study must end long
before its work could, with its finished points on disk, its workers gone and exit code 130.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from millctl.errors import ExitCode
from millctl.studies.store import ResultsStore
from tests.conftest import CONFIG_FILE, REPO
from tests.support.pace import Deadline, stretched

LONG = """
[study]
name = "long on Set A"
seed = 3
variant = "corrected"

[parameters.rotary_rpm]
grid = { start = 60, stop = 260, num = 40 }

[parameters.vibration_rpm]
grid = { start = 300, stop = 1200, num = 40 }

[metrics]
names = ["sim_impact_rate_hz"]
revolutions = 6.0

[objective]
maximize = "sim_impact_rate_hz"
"""
POINTS = 1600


def _start(tmp_path: Path, out: Path, workers: int = 2) -> subprocess.Popen[str]:
    study = tmp_path / "long.toml"
    study.write_text(LONG)
    command = [sys.executable, "-m", "millctl", "--config", str(CONFIG_FILE), "study", str(study)]
    command += ["--out", str(out), "--csv", "--workers", str(workers)]
    return subprocess.Popen(
        command, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )


def _rows(out: Path) -> int:
    if not out.exists():
        return 0
    return max(len(out.read_text().splitlines()) - 2, 0)  # less the fingerprint and the header


def _descendants(pid: int) -> set[int]:
    """Every live process below ``pid`` (from /proc: the forkserver and the workers)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        if fields[0] != "Z":
            children.setdefault(int(fields[1]), []).append(int(entry.name))
    found: set[int] = set()
    todo = [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.add(child)
            todo.append(child)
    return found


def _alive(pids: set[int]) -> set[int]:
    alive = set()
    for pid in pids:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if state != "Z":
            alive.add(pid)
    return alive


def _running_with_points(proc: subprocess.Popen[str], out: Path) -> set[int]:
    """Wait until some points are saved and both workers run; their PIDs (and the forkserver's)."""
    deadline = Deadline(120.0)
    while True:
        assert proc.poll() is None, proc.communicate()
        workers = _descendants(proc.pid)
        if _rows(out) > 0 and len(workers) >= 3:
            return workers
        if deadline.expired():
            proc.kill()
            pytest.fail(f"no saved point and two workers within {deadline.describe()}: {proc.communicate()}")
        time.sleep(0.05)


def _gone(pids: set[int]) -> set[int]:
    deadline = Deadline(20.0)
    while _alive(pids) and not deadline.expired():
        time.sleep(0.05)
    return _alive(pids)


@pytest.mark.parametrize("to_group", [True, False], ids=["ctrl-c-to-the-group", "sigint-to-the-parent"])
def test_sigint_stops_the_study_with_its_finished_points_saved(tmp_path: Path, to_group: bool) -> None:
    out = tmp_path / "long.csv"
    proc = _start(tmp_path, out)
    workers = _running_with_points(proc, out)
    if to_group:
        os.killpg(proc.pid, signal.SIGINT)
    else:
        os.kill(proc.pid, signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=stretched(20.0))
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail(f"the study did not stop on SIGINT: {proc.communicate()}")
    assert proc.returncode == ExitCode.INTERRUPTED, err
    saved = _rows(out)
    assert 0 < saved < POINTS
    assert f"interrupted: {saved} finished points are in {out}" in " ".join(err.split())
    assert not _gone(workers), "workers outlived the study"
    # every saved row is complete, and a rerun takes them as done (the lock was let go)
    store = ResultsStore(out, "")
    rows, _ = store._read_csv()
    assert len(rows) == saved and all(r["events"] > 0 or r["sim_impact_rate_hz"] == 0.0 for r in rows)


def test_workers_die_with_a_killed_study(tmp_path: Path) -> None:
    out = tmp_path / "long.csv"
    proc = _start(tmp_path, out)
    workers = _running_with_points(proc, out)
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate()
    left = _gone(workers)
    if left:
        for pid in left:
            os.kill(pid, signal.SIGKILL)
    assert not left, f"workers {sorted(left)} outlived their killed study"


def test_a_second_run_on_the_same_results_file_is_refused_with_the_holders_pid(tmp_path: Path) -> None:
    out = tmp_path / "long.csv"
    holder = ResultsStore(out, "")
    holder.lock()
    try:
        proc = _start(tmp_path, out, workers=1)
        _, err = proc.communicate(timeout=stretched(60.0))
    finally:
        holder.unlock()
    assert proc.returncode == ExitCode.INVALID_INPUT, err
    assert f"in use by another study run (PID {os.getpid()}" in " ".join(err.split())
    assert not out.exists()  # nothing written, nothing lost
