"""pytest-timeout's bound stretches with measured load, as every process wait does (tests/support/timeouts.py)."""

from __future__ import annotations

import re

import pytest

from tests.support import pace, timeouts
from tests.unit.support.test_tiers import PLAIN


@pytest.fixture
def eight_runnable_on_two_cpus(monkeypatch: pytest.MonkeyPatch) -> None:
    """The load as pace measures it: 4 tasks per CPU, so a runnable process gets a quarter of one."""
    monkeypatch.setattr(pace, "runnable_per_cpu", lambda: 4.0)
    monkeypatch.delenv("MILLCTL_TIME_SCALE", raising=False)


def test_the_configured_bound_stretches_by_the_cpu_share(eight_runnable_on_two_cpus: None) -> None:
    assert timeouts.timeout_s(120.0, from_command_line=False) == pytest.approx(480.0)


def test_on_an_idle_machine_the_bound_is_as_configured(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(pace, "runnable_per_cpu", lambda: 0.2)
    monkeypatch.delenv("MILLCTL_TIME_SCALE", raising=False)
    assert timeouts.timeout_s(120.0, from_command_line=False) == 120.0


def test_a_bound_from_the_command_line_is_the_callers_and_kept(eight_runnable_on_two_cpus: None) -> None:
    assert timeouts.timeout_s(900.0, from_command_line=True) == 900.0


def test_no_timeout_stays_none(eight_runnable_on_two_cpus: None) -> None:
    assert timeouts.timeout_s(0.0, from_command_line=False) == 0.0


def test_the_stretch_is_capped_so_a_hang_still_fails(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(pace, "runnable_per_cpu", lambda: 500.0)
    monkeypatch.delenv("MILLCTL_TIME_SCALE", raising=False)
    assert timeouts.timeout_s(120.0, from_command_line=False) == pytest.approx(120.0 * pace.MAX_STRETCH)


INNER = """
import threading

def test_timer():
    timers = [t for t in threading.enumerate() if t.name.startswith("pytest_timeout ")]
    assert len(timers) == 1, timers
    print(f"TIMER {timers[0].interval}")
"""


def timer_of_inner_test(pytester: pytest.Pytester, *args: str) -> float:
    """The interval pytest-timeout set for a test of an inner session (ini ``timeout = 120``), in s."""
    pytester.makeini("[pytest]\ntimeout = 120\ntimeout_method = thread\n")
    pytester.makeconftest("from tests.support.timeouts import pytest_timeout_set_timer")
    pytester.makepyfile(test_inner=INNER)
    result = pytester.runpytest_inprocess(*PLAIN, "-s", *args)
    result.assert_outcomes(passed=1)
    found = re.search(r"TIMER (\S+)", result.stdout.str())
    assert found is not None, result.stdout.str()
    return float(found[1])


def test_pytest_timeout_sets_its_timer_to_the_stretched_bound(
    pytester: pytest.Pytester, eight_runnable_on_two_cpus: None
) -> None:
    assert timer_of_inner_test(pytester) == pytest.approx(480.0)


def test_pytest_timeout_keeps_a_timeout_given_on_the_command_line(
    pytester: pytest.Pytester, eight_runnable_on_two_cpus: None
) -> None:
    assert timer_of_inner_test(pytester, "--timeout", "120") == 120.0
