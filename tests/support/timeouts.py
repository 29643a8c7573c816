"""pytest-timeout's per-test bound, stretched with the load measured as each test starts (issue 14).

The ``timeout`` in pyproject.toml (120 s; an environment's ``PYTEST_TIMEOUT`` likewise) is a safety net
sized for a test on an idle machine, not a measurement: it is there so that a hang fails the test instead
of the whole run. A unit test is CPU-bound, so on a shared machine its wall time grows with the tasks
competing for the CPUs, and its bound only waits for a process (pytest's own): it stretches as every such
wait does, by :func:`tests.support.pace.stretched` (the CPU share a runnable process gets as the test
starts, at most ``pace.MAX_STRETCH`` times, so a hang still fails; and ``$MILLCTL_TIME_SCALE``).

A ``--timeout`` given on the command line is the caller's own bound, sized for where it runs (the hil
tiers' 900 s, the VM's 120 s times its measured emulation factor, the fuzz job's hour), and is kept as
given, as is every bound of a session that was given one there.

Loaded by ``tests/conftest.py``; without pytest-timeout it does nothing.
"""

from __future__ import annotations

from typing import Any

import pytest

from tests.support.pace import stretched


def timeout_s(configured_s: float, *, from_command_line: bool) -> float:
    """The bound for a test starting now (s): ``configured_s`` stretched with load, unless the command line gave it.

    0 (or less) means no timeout to pytest-timeout, and stays so.
    """
    if from_command_line or not configured_s > 0:
        return configured_s
    return stretched(configured_s)


@pytest.hookimpl(tryfirst=True, optionalhook=True)
def pytest_timeout_set_timer(item: pytest.Item, settings: Any) -> object:
    """Set pytest-timeout's timer (its own hook implementation) with the bound stretched for this test."""
    from_command_line = item.config.getoption("timeout", None) is not None
    stretched_settings = settings._replace(timeout=timeout_s(settings.timeout, from_command_line=from_command_line))
    timeout_plugin: Any = item.config.pluginmanager.get_plugin("timeout")
    return timeout_plugin.pytest_timeout_set_timer(item=item, settings=stretched_settings)


__all__ = ["pytest_timeout_set_timer", "timeout_s"]
