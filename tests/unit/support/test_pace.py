"""Process waits stretch with measured load; a hang still fails (tests/support/pace.py, issue 14)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tests.support import pace


class FakeLoad:
    """/proc/loadavg and the monotonic clock, as a test sets them."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, tmp_path: Path, cpus: int = 2) -> None:
        self.file = tmp_path / "loadavg"
        self.now = 100.0
        self.set(0.0, 1)
        real_path = Path
        monkeypatch.setattr(pace, "Path", lambda p: self.file if p == "/proc/loadavg" else real_path(p))
        monkeypatch.setattr("tests.support.pace.os.cpu_count", lambda: cpus)
        monkeypatch.setattr("tests.support.pace.time.monotonic", lambda: self.now)
        monkeypatch.delenv("MILLCTL_TIME_SCALE", raising=False)

    def set(self, load_1min: float, runnable: int) -> None:
        self.file.write_text(f"{load_1min:.2f} 0.50 0.40 {runnable}/300 4242\n")


@pytest.fixture
def load(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> FakeLoad:
    return FakeLoad(monkeypatch, tmp_path)


def test_an_idle_machine_gives_a_whole_cpu(load: FakeLoad) -> None:
    load.set(0.3, 1)  # only the reader itself runs
    assert pace.cpu_share() == 1.0
    assert pace.stretched(30.0) == 30.0


def test_eight_runnable_tasks_on_two_cpus_give_a_quarter(load: FakeLoad) -> None:
    load.set(8.0, 3)
    assert pace.cpu_share() == pytest.approx(0.25)
    assert pace.stretched(30.0) == pytest.approx(120.0)


def test_a_burst_counts_before_the_load_average_catches_up(load: FakeLoad) -> None:
    load.set(0.5, 7)  # 6 others runnable now, on 2 CPUs
    assert pace.cpu_share() == pytest.approx(1 / 3)


def test_the_stretch_is_capped_so_a_hang_still_fails(load: FakeLoad) -> None:
    load.set(500.0, 500)
    assert pace.cpu_share() == pytest.approx(1 / pace.MAX_STRETCH)


def test_a_deadline_runs_at_the_cpu_share_measured_at_each_check(load: FakeLoad) -> None:
    deadline = pace.Deadline(10.0)
    load.now += 6.0  # idle: 6 s count fully
    assert not deadline.expired()
    load.set(4.0, 1)  # 2 runnable per CPU: the next 6 s count as 3
    load.now += 6.0
    assert not deadline.expired()
    load.now += 2.0  # 6 + 3 + 1 = 10
    assert deadline.expired()
    assert "waited 14.0 s" in deadline.describe()


def test_the_vm_scale_multiplies_every_wait(load: FakeLoad, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MILLCTL_TIME_SCALE", "7.5")
    assert pace.stretched(2.0) == 15.0
    deadline = pace.Deadline(2.0)
    load.now += 14.9
    assert not deadline.expired()
    load.now += 0.2
    assert deadline.expired()


@pytest.mark.parametrize("bad", ["0.5", "fast", "nan"])
def test_a_bad_time_scale_is_refused_with_its_value(monkeypatch: pytest.MonkeyPatch, bad: str) -> None:
    monkeypatch.setenv("MILLCTL_TIME_SCALE", bad)
    with pytest.raises(ValueError, match="MILLCTL_TIME_SCALE must be"):
        pace.time_scale()


# --- calibration: the VM's slowdown against the host ---------------------------------------------------------------


def test_the_slowdown_is_the_measured_time_over_the_reference() -> None:
    assert pace.slowdown_against(0.002, measured_s=0.05) == pytest.approx(25.0)


def test_a_machine_faster_than_the_reference_counts_as_no_slowdown() -> None:
    assert pace.slowdown_against(0.004, measured_s=0.001) == 1.0  # never below 1: waits only ever stretch


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan")])
def test_a_bad_reference_is_refused_with_its_value(bad: float) -> None:
    with pytest.raises(ValueError, match="calibration reference must be a positive time"):
        pace.slowdown_against(bad, measured_s=1.0)


def test_the_host_reference_is_the_fastest_cpu_time_and_the_vm_figure_the_median_wall_time(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    runs = iter([0.0, 5.0, 5.0, 6.0, 6.0, 9.0])  # three runs: 5, 1 and 3 s on whichever clock is read
    monkeypatch.setattr(pace, "_workload", lambda: None)
    monkeypatch.setattr(time, "process_time", lambda: next(runs))
    assert pace.calibration_s(repeats=3, clock="cpu") == 1.0
    runs = iter([0.0, 5.0, 5.0, 6.0, 6.0, 9.0])
    monkeypatch.setattr(time, "perf_counter", lambda: next(runs))
    assert pace.calibration_s(repeats=3, clock="wall") == 3.0


def test_an_unknown_calibration_clock_is_refused() -> None:
    with pytest.raises(ValueError, match="'cpu' or 'wall', got 'tsc'"):
        pace.calibration_s(clock="tsc")


def test_the_command_line_prints_the_reference_and_the_scale(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(pace, "calibration_s", lambda repeats=7, clock="wall": 0.006 if clock == "cpu" else 0.1)
    assert pace.main(["--reference"]) == 0
    assert capsys.readouterr() == ("0.006000\n", "")
    assert pace.main(["--scale", "0.004"]) == 0
    assert capsys.readouterr().out == "25.00\n"
    assert pace.main([]) == 2


def test_a_host_faster_than_the_slowest_passing_one_gives_that_ones_reference_and_says_so(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Run 4 of e77800c: the host measured 3.05 ms at a quiet moment, and its VM's scale read 46 instead of ~29."""
    monkeypatch.setattr(pace, "calibration_s", lambda repeats=7, clock="wall": 0.00305 if clock == "cpu" else 0.1)
    assert pace.host_reference_s() == 0.0048
    assert pace.main(["--reference"]) == 0
    out, err = capsys.readouterr()
    assert out == "0.004800\n"
    assert "0.003050 s of CPU" in err and "SLOWEST_PASSING_HOST_S" in err
    assert round(pace.slowdown_against(float(out), 0.1412), 2) == 29.42


def test_the_load_scale_is_measured_now_against_the_hosts_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MILLCTL_TIME_SCALE", "20")
    monkeypatch.delenv(pace.REFERENCE_ENV, raising=False)
    assert pace.slowdown_now() == 20.0  # no reference (the host): the run's scale
    monkeypatch.setenv(pace.REFERENCE_ENV, "0.002")
    monkeypatch.setattr(pace, "calibration_s", lambda repeats=7, clock="wall": 0.09)
    assert pace.slowdown_now() == pytest.approx(45.0)  # the host got busier since the run measured 20
    monkeypatch.setattr(pace, "calibration_s", lambda repeats=7, clock="wall": 0.01)
    assert pace.slowdown_now() == 20.0  # never below the run's scale


def test_each_vm_test_measures_the_scale_again_never_below_the_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(pace.REFERENCE_ENV, "0.002")
    monkeypatch.setenv(pace.MEASURED_ENV, "1")
    monkeypatch.setattr(pace, "calibration_s", lambda repeats=7, clock="wall": 0.1)
    assert pace.scale_for_a_test(24.0) == pytest.approx(50.0)  # the host got busier since the VM booted
    monkeypatch.setattr(pace, "calibration_s", lambda repeats=7, clock="wall": 0.02)
    assert pace.scale_for_a_test(24.0) == 24.0  # a calmer moment does not tighten what the run was sized for
    monkeypatch.setenv(pace.MEASURED_ENV, "0")
    monkeypatch.setattr(pace, "calibration_s", lambda repeats=7, clock="wall": 0.1)
    assert pace.scale_for_a_test(30.0) == 30.0  # a forced figure is used as it is
    monkeypatch.setenv(pace.MEASURED_ENV, "1")
    monkeypatch.delenv(pace.REFERENCE_ENV)
    assert pace.scale_for_a_test(1.0) == 1.0  # the host: no reference, no measurement
