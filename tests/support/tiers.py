"""A pytest plugin for CI tiers: a tier that skips what it is meant to run fails, and says so.

Loaded by ``tests/conftest.py``. Without options it changes nothing (a
developer's ``pytest tests/hil`` skips udp_multicast outside a network
namespace, as before). CI (``.ci/test``, ``tests/vm/guest``) names each tier:

``--tier NAME``
    The tier's name. A test that skips, at collection, setup or call, is
    reported as **failed** with the tier's name and the skip's reason, unless
    the reason matches a ``--may-skip`` pattern. xfail is not a skip.
``--may-skip REGEX``
    A skip reason this tier accepts (repeatable; ``re.search``). For skips that
    are structural, such as a case that needs two processes on python-can's
    in-process ``virtual`` bus; each accepted skip is still counted and listed.
``--transports a,b``
    Keep only the cases of these transports (the ``transport`` parameter of the
    hil fixtures); the others are deselected, not skipped, because another tier
    runs them (socketcan runs in the VM).

At the end the tier prints its closing line,
``TIER unit: 812 passed, 0 failed, 0 errors, 0 skipped (3 deselected)``, and
appends it to the file named by ``$MILLCTL_TIER_SUMMARY`` (if set) for
``.ci/test`` and ``.ci/run`` to print together.

With ``$MILLCTL_FAILURES_LOG`` set, each failure and error is appended to that file as it
happens, with its traceback (the VM's run, ``tests/vm/guest``, may be stopped by its timeout
before pytest prints its summary: the log still says what failed, and why). With
``$MILLCTL_PROGRESS_LOG`` set, the number of tests collected, each test's start and each test's
outcome go to that file as they happen, so that a cut run can say how far it got and what was
running (``tests/support/progress.py`` reads it).

Under pytest-xdist (``-n 2``, the unit tier) the workers collect and run the
tests and the controller only counts their reports: a worker's skip is turned
into a failure where it happens (its report reaches the controller as failed),
the closing line is the controller's alone, and the deselected count, which
xdist does not forward, comes back in each worker's ``workeroutput``.
"""

from __future__ import annotations

import os
import re
import time
from collections.abc import Generator
from pathlib import Path
from typing import Any

import pytest
from _pytest.reports import CollectReport, TestReport

SUMMARY_ENV = "MILLCTL_TIER_SUMMARY"
FAILURES_ENV = "MILLCTL_FAILURES_LOG"
"""The file each failure is appended to as it happens (tests/vm/guest sets it in the VM)."""
PROGRESS_ENV = "MILLCTL_PROGRESS_LOG"
"""The file each test's start and outcome are appended to as they happen (tests/vm/guest sets it in the VM)."""
COUNTED = ("passed", "failed", "error", "skipped", "deselected", "xfailed", "xpassed")
DESELECTED_KEY = "millctl_deselected"
"""The key of a pytest-xdist worker's ``workeroutput`` that carries how many tests it deselected."""
_deselected_by_workers = pytest.StashKey[int]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("millctl tiers", "CI tiers: skipping what a tier must run is a failure")
    group.addoption("--tier", default=None, help="name of the CI tier; a skip in it fails unless --may-skip allows it")
    group.addoption(
        "--may-skip", action="append", default=[], metavar="REGEX", help="a skip reason this tier accepts (repeatable)"
    )
    group.addoption(
        "--transports",
        default=None,
        metavar="NAMES",
        help="comma-separated transports whose hil cases run here; the others are deselected",
    )


def _tier(config: pytest.Config) -> str | None:
    name: str | None = config.getoption("--tier")
    return name


def _accepted(config: pytest.Config, reason: str) -> bool:
    patterns: list[str] = config.getoption("--may-skip")
    return any(re.search(pattern, reason) for pattern in patterns)


def skip_reason(report: TestReport | CollectReport) -> str:
    """The reason a skipped report gives (pytest stores it as ``(path, lineno, "Skipped: reason")``)."""
    longrepr = report.longrepr
    if isinstance(longrepr, tuple) and len(longrepr) == 3:
        return str(longrepr[2]).removeprefix("Skipped: ")
    return str(longrepr)


def _fail_skip(report: TestReport | CollectReport, tier: str) -> None:
    reason = skip_reason(report)
    report.outcome = "failed"
    report.longrepr = (
        f"tier {tier!r} must run this case, but it skipped: {reason}\n"
        "(a skip in a CI tier is a failure, so a tier cannot pass while testing less than it claims; "
        "tests/support/tiers.py)"
    )


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, Any, None]:
    outcome = yield
    report: TestReport = outcome.get_result()
    tier = _tier(item.config)
    if tier and report.skipped and not hasattr(report, "wasxfail") and not _accepted(item.config, skip_reason(report)):
        _fail_skip(report, tier)


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> Generator[None, Any, None]:
    outcome = yield
    report: CollectReport = outcome.get_result()
    tier = _tier(collector.config)
    if tier and report.skipped and not _accepted(collector.config, skip_reason(report)):
        _fail_skip(report, tier)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    wanted: str | None = config.getoption("--transports")
    if wanted is None:
        return
    keep_names = {name.strip() for name in wanted.split(",") if name.strip()}
    kept: list[pytest.Item] = []
    dropped: list[pytest.Item] = []
    for item in items:
        callspec = getattr(item, "callspec", None)
        transport = callspec.params.get("transport") if callspec is not None else None
        (dropped if transport is not None and transport not in keep_names else kept).append(item)
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = kept


def pytest_runtest_logreport(report: TestReport) -> None:
    """Append a failed setup, call or teardown to ``$MILLCTL_FAILURES_LOG`` at once; count it for the progress log."""
    _log_failure(report, report.when)
    _record_outcome(report)


def pytest_collectreport(report: CollectReport) -> None:
    """Append a collection error to ``$MILLCTL_FAILURES_LOG`` at once."""
    _log_failure(report, "collection")


def _log_failure(report: TestReport | CollectReport, when: str | None) -> None:
    path = os.environ.get(FAILURES_ENV)
    if not path or not report.failed or os.environ.get("PYTEST_XDIST_WORKER"):  # the controller logs workers' reports
        return
    stamp = time.strftime("%H:%M:%S")
    with Path(path).open("a", encoding="utf-8") as out:
        out.write(f"=== {report.nodeid} ({when}, {stamp})\n{report.longreprtext}\n")
        out.flush()


# --- progress: how far a run got (read by tests/support/progress.py when the run is cut) ----------------------

_outcome_so_far: dict[str, str] = {}
"""Each running test's outcome from the reports of its phases so far (setup, call, teardown)."""


def _append_progress(line: str) -> None:
    path = os.environ.get(PROGRESS_ENV)
    if not path or os.environ.get("PYTEST_XDIST_WORKER"):  # the controller logs workers' tests
        return
    with Path(path).open("a", encoding="utf-8") as out:
        out.write(line + "\n")
        out.flush()


def outcome_after(earlier: str, report: TestReport) -> str:
    """A test's outcome after one more phase's report, counted as pytest counts it: a failed setup or
    teardown is an ``error`` and a failed call ``failed`` (either one stays), a skip ``skipped``, an
    expected failure ``xfailed`` or ``xpassed``, else ``passed``."""
    if earlier in ("failed", "error"):
        return earlier
    if report.failed:
        return "failed" if report.when == "call" else "error"
    expected_to_fail = hasattr(report, "wasxfail")
    if report.skipped:
        return "xfailed" if expected_to_fail else "skipped"
    if report.when == "call" and expected_to_fail:
        return "xpassed"
    return earlier


def _record_outcome(report: TestReport) -> None:
    _outcome_so_far[report.nodeid] = outcome_after(_outcome_so_far.get(report.nodeid, "passed"), report)


def pytest_collection_finish(session: pytest.Session) -> None:
    """Note how many tests this run will run (after deselection) in ``$MILLCTL_PROGRESS_LOG``."""
    _append_progress(f"collected {len(session.items)}")


def pytest_runtest_logstart(nodeid: str) -> None:
    """Note a test's start in ``$MILLCTL_PROGRESS_LOG``: a cut run then names the test it was in."""
    _append_progress(f"start {time.strftime('%H:%M:%S')} {nodeid}")


def pytest_runtest_logfinish(nodeid: str) -> None:
    """Note a test's outcome in ``$MILLCTL_PROGRESS_LOG`` once all its phases have reported."""
    _append_progress(f"{_outcome_so_far.pop(nodeid, 'passed')} {time.strftime('%H:%M:%S')} {nodeid}")


def _is_xdist_worker(config: pytest.Config) -> bool:
    return hasattr(config, "workerinput")


def pytest_sessionfinish(session: pytest.Session) -> None:
    """In a pytest-xdist worker: hand the number of deselected tests to the controller."""
    config = session.config
    if _is_xdist_worker(config):
        reporter = config.pluginmanager.get_plugin("terminalreporter")
        deselected = len(reporter.stats.get("deselected", [])) if reporter is not None else 0
        config.workeroutput[DESELECTED_KEY] = deselected  # type: ignore[attr-defined]


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node: Any, error: object) -> None:
    """In the pytest-xdist controller: every worker collects the whole tier, so each deselects the same tests."""
    count = int(getattr(node, "workeroutput", {}).get(DESELECTED_KEY, 0))
    config: pytest.Config = node.config
    config.stash[_deselected_by_workers] = max(config.stash.get(_deselected_by_workers, 0), count)


def closing_line(tier: str, stats: dict[str, list[Any]], deselected_elsewhere: int = 0) -> str:
    """``TIER name: N passed, N failed, N errors, N skipped`` (+ deselected/xfail when there are any).

    ``deselected_elsewhere``: tests the xdist workers deselected (the controller's own stats have none).
    """
    n = {key: len(stats.get(key, [])) for key in COUNTED}
    n["deselected"] = max(n["deselected"], deselected_elsewhere)
    line = f"{tier}: {n['passed']} passed, {n['failed']} failed, {n['error']} errors, {n['skipped']} skipped"
    extras = [f"{n[key]} {key}" for key in ("deselected", "xfailed", "xpassed") if n[key]]
    return line + (f" ({', '.join(extras)})" if extras else "")


def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    tier = _tier(config)
    if tier is None or _is_xdist_worker(config):
        return
    stats: dict[str, list[Any]] = terminalreporter.stats
    line = closing_line(tier, stats, config.stash.get(_deselected_by_workers, 0))
    accepted = sorted({skip_reason(r) for r in stats.get("skipped", [])})
    terminalreporter.write_sep("=", f"TIER {line}")
    for reason in accepted:
        terminalreporter.write_line(f"  accepted skip ({tier}): {reason}")
    if path := os.environ.get(SUMMARY_ENV):
        with Path(path).open("a", encoding="utf-8") as out:
            out.write(f"{line}{'' if exitstatus == 0 else f' [pytest exit {int(exitstatus)}]'}\n")
