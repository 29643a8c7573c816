"""The CI tiers' plugin (tests/support/tiers.py): a tier that skips what it must run fails.

Issue 14: outside a network namespace 46 of 54 transport cases skipped and CI
stayed green. Each test runs a small pytest session in-process (pytester).
"""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]

CONFTEST = """
from tests.support.tiers import (
    pytest_addoption, pytest_collection_finish, pytest_collection_modifyitems, pytest_collectreport,
    pytest_make_collect_report, pytest_runtest_logfinish, pytest_runtest_logreport, pytest_runtest_logstart,
    pytest_runtest_makereport, pytest_sessionfinish, pytest_terminal_summary, pytest_testnodedown,
)
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]

@pytest.fixture(params=["virtual", "udp_multicast", "socketcan"])
def transport(request):
    if request.param == "udp_multicast":
        pytest.skip("udp_multicast runs only in a private network namespace")
    return request.param
"""

TESTS = """
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]

def test_plain():
    assert True

def test_on(transport):
    if transport == "virtual":
        pytest.skip("virtual frames stay inside one process")

@pytest.mark.xfail(reason="documented defect", strict=True)
def test_known_defect():
    assert False
"""


# The inner sessions do without the heavy plugins; textual-snapshot's would delete the outer session's files.
PLAIN = tuple(
    arg
    for plugin in ("textual-snapshot", "asyncio", "schemathesis", "hypothesispytest", "cacheprovider")
    for arg in ("-p", f"no:{plugin}")
)


def run(pytester: pytest.Pytester, *args: str) -> pytest.RunResult:
    return pytester.runpytest_inprocess(*PLAIN, *args)


@pytest.fixture(autouse=True)
def no_outer_summary(monkeypatch: pytest.MonkeyPatch) -> None:
    """The inner sessions must not write into the summary, failure or progress log of the tier running these tests."""
    monkeypatch.delenv("MILLCTL_TIER_SUMMARY", raising=False)
    monkeypatch.delenv("MILLCTL_FAILURES_LOG", raising=False)
    monkeypatch.delenv("MILLCTL_PROGRESS_LOG", raising=False)


@pytest.fixture
def suite(pytester: pytest.Pytester) -> pytest.Pytester:
    pytester.makeconftest(CONFTEST)
    pytester.makepyfile(test_suite=TESTS)
    return pytester


def test_without_a_tier_skips_stay_skips(suite: pytest.Pytester) -> None:
    result = run(suite)
    result.assert_outcomes(passed=2, skipped=2, xfailed=1)
    assert result.ret == 0


def test_a_skip_in_a_tier_fails_and_names_the_tier_and_the_reason(suite: pytest.Pytester) -> None:
    result = run(suite, "--tier", "hil-transport")
    assert result.ret == 1
    # setup-time skip (the fixture) becomes an error, call-time skip (the test body) a failure
    result.assert_outcomes(passed=2, failed=1, errors=1, xfailed=1)
    result.stdout.fnmatch_lines(
        ["*tier 'hil-transport' must run this case, but it skipped: udp_multicast runs only in a private*"]
    )


def test_an_accepted_skip_passes_and_is_still_counted(suite: pytest.Pytester) -> None:
    result = run(suite, "--tier", "t", "--may-skip", "inside one process", "--may-skip", "private network namespace")
    assert result.ret == 0
    result.assert_outcomes(passed=2, skipped=2, xfailed=1)
    result.stdout.fnmatch_lines(["*accepted skip (t): virtual frames stay inside one process*"])


def test_transports_deselects_the_cases_of_other_transports(suite: pytest.Pytester) -> None:
    result = run(suite, "--tier", "vcan", "--transports", "socketcan")
    assert result.ret == 0
    result.assert_outcomes(passed=2, deselected=2, xfailed=1)


def test_a_skip_at_collection_fails_too(pytester: pytest.Pytester) -> None:
    pytester.makeconftest(CONFTEST)
    pytester.makepyfile(test_gone="import pytest\npytest.importorskip('no_such_module_anywhere')\n")
    result = run(pytester, "--tier", "unit")
    assert result.ret != 0
    result.stdout.fnmatch_lines(["*tier 'unit' must run this case, but it skipped: could not import*"])


def test_the_closing_line_counts_each_outcome_and_goes_to_the_summary_file(
    suite: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    summary = suite.path / "tiers.txt"
    monkeypatch.setenv("MILLCTL_TIER_SUMMARY", str(summary))
    run(suite, "--tier", "hil-transport", "--may-skip", "inside one process")
    expected = "hil-transport: 2 passed, 0 failed, 1 errors, 1 skipped (1 xfailed) [pytest exit 1]"
    assert summary.read_text().splitlines() == [expected]


def test_under_xdist_the_controller_alone_writes_the_closing_line_with_the_workers_counts(
    suite: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The unit tier runs on two pytest-xdist workers: a skip still fails, and one closing line counts it all."""
    summary = suite.path / "tiers.txt"
    monkeypatch.setenv("MILLCTL_TIER_SUMMARY", str(summary))
    monkeypatch.setenv("PYTHONPATH", str(REPO))
    monkeypatch.setenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")  # three interpreters: xdist is the one plugin needed
    result = suite.runpytest_subprocess(
        "-p", "xdist", "-n", "2", "--tier", "vcan", "--transports", "virtual,udp_multicast", "-k", "not test_plain"
    )
    assert result.ret == 1
    result.stdout.fnmatch_lines(["*tier 'vcan' must run this case, but it skipped: *"])
    # test_plain and socketcan's case deselected (by -k and --transports, in each worker); the virtual case's
    # call-time skip a failure, udp_multicast's setup-time skip an error
    expected = "vcan: 0 passed, 1 failed, 1 errors, 0 skipped (2 deselected, 1 xfailed) [pytest exit 1]"
    assert summary.read_text().splitlines() == [expected]


def logged_session(pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch, env: str, **files: str) -> Path:
    """An inner session of ``files`` whose log ``env`` names (returned); it is no xdist worker, wherever this runs."""
    log = pytester.path / f"{env.lower()}.txt"
    monkeypatch.setenv(env, str(log))
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)
    pytester.makeconftest(CONFTEST)
    pytester.makepyfile(**files)
    return log


FAILING = """
import pytest

@pytest.fixture
def broken():
    raise RuntimeError("the service never came up")

def test_fine():
    pass

def test_wrong():
    assert 1 + 1 == 3, "arithmetic"

def test_needs(broken):
    pass
"""


def test_each_failure_is_logged_with_its_traceback_as_it_happens(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The VM's run can be cut by its timeout before pytest's summary: the log already holds every failure."""
    log = logged_session(
        pytester,
        monkeypatch,
        "MILLCTL_FAILURES_LOG",
        test_failing=FAILING,
        test_broken_import="import no_such_module_anywhere\n",
    )
    result = run(pytester, "--tier", "vcan", "--continue-on-collection-errors")
    assert result.ret == 1
    entries = log.read_text().split("=== ")[1:]
    heads = [entry.splitlines()[0].rsplit(",", 1)[0] for entry in entries]
    assert heads == [
        "test_broken_import.py (collection",
        "test_failing.py::test_wrong (call",
        "test_failing.py::test_needs (setup",
    ]
    assert "No module named 'no_such_module_anywhere'" in entries[0]
    assert "AssertionError: arithmetic" in entries[1]
    assert "RuntimeError: the service never came up" in entries[2]


def progress_words(log: Path) -> list[str]:
    """The progress log without its clock: ``collected N`` and ``WORD NODEID`` lines."""
    lines = log.read_text().splitlines()
    return [line if line.startswith("collected ") else " ".join(line.split(" ")[::2]) for line in lines]


def test_each_tests_start_and_outcome_go_to_the_progress_log_as_they_happen(
    suite: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    log = suite.path / "progress.log"
    monkeypatch.setenv("MILLCTL_PROGRESS_LOG", str(log))
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)  # the inner session is no worker, wherever this runs
    run(suite, "--tier", "hil-transport", "--may-skip", "inside one process", "--transports", "virtual,udp_multicast")
    assert progress_words(log) == [
        "collected 4",
        "start test_suite.py::test_plain",
        "passed test_suite.py::test_plain",
        "start test_suite.py::test_on[virtual]",
        "skipped test_suite.py::test_on[virtual]",
        "start test_suite.py::test_on[udp_multicast]",
        "error test_suite.py::test_on[udp_multicast]",
        "start test_suite.py::test_known_defect",
        "xfailed test_suite.py::test_known_defect",
    ]
    stamp = log.read_text().splitlines()[1].split(" ")[1]
    assert len(stamp) == 8 and stamp[2] == stamp[5] == ":", stamp


CUT = """
import os

def test_first():
    pass

def test_wrong():
    assert 2 + 2 == 5

def test_cut():
    os._exit(3)  # the process ends here, as a VM stopped by its timeout does: no summary

def test_never():
    pass
"""


def test_a_run_cut_mid_test_leaves_a_log_that_says_how_far_it_got(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    """What tests/vm/run prints for the vcan tier when its VM is stopped before pytest's summary."""
    log = logged_session(pytester, monkeypatch, "MILLCTL_PROGRESS_LOG", test_cut=CUT)
    monkeypatch.setenv("PYTHONPATH", str(REPO))
    monkeypatch.setenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")
    result = pytester.runpytest_subprocess("--tier", "vcan")
    assert result.ret == 3
    from tests.support.progress import cut_line, read_progress

    line = cut_line("vcan", read_progress(log.read_text()), "the VM's timeout, 60 s")
    assert line == (
        "vcan: FAILED: cut (the VM's timeout, 60 s) after 2 of 4 cases: 1 passed, 1 failed, 0 errors, 0 skipped; "
        "in test_cut.py::test_cut; 1 not started"
    )


def test_the_root_conftest_exports_every_hook_of_the_plugin() -> None:
    """The plugin acts through tests/conftest.py, which imports its hooks by name: a hook left out does nothing."""
    import tests.conftest
    from tests.support import tiers

    hooks = {name for name in vars(tiers) if name.startswith("pytest_")}
    assert len(hooks) >= 12, sorted(hooks)
    assert hooks - set(tests.conftest.__all__) == set()
    assert all(getattr(tests.conftest, name) is getattr(tiers, name) for name in hooks)
