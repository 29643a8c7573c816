"""Fixtures shared by every tier, the CI tiers' plugin, and the Hypothesis profiles.

Hypothesis runs the ``ci`` profile unless told otherwise: derandomized (the
examples are a fixed function of each test, so a run can be repeated), after
replaying the **stored examples** read-only: ``tests/examples/hypothesis``, the
committed example database of what the random search found
(tests/support/examples.py), besides the hand-picked hard cases written as
``@example`` decorators and explicit API cases in the tests themselves.

The random search is the opt-in, longer ``fuzz`` job (``bash .ci/fuzz``:
``--hypothesis-profile fuzz -m ''``): many more examples and fresh randomness.
The minimal failing example of each bug it finds is written to
``tests/examples/hypothesis``; commit it with the fix, and every CI run replays
it. The fuzz job does not replay the stored examples itself (CI does), so it
never deletes one that passes again.
"""

from __future__ import annotations

import gc
from collections.abc import Generator
from pathlib import Path

import pytest
from hypothesis import Phase, settings

from millctl.config import MillConfig, load_config
from tests.support import examples, mutation_tests, timeouts, virtual_bus
from tests.support.realtime import take_over
from tests.support.tiers import (
    pytest_addoption,
    pytest_collection_finish,
    pytest_collection_modifyitems,
    pytest_collectreport,
    pytest_make_collect_report,
    pytest_runtest_logfinish,
    pytest_runtest_logreport,
    pytest_runtest_logstart,
    pytest_runtest_makereport,
    pytest_sessionfinish,
    pytest_terminal_summary,
    pytest_testnodedown,
)

__all__ = [  # the CI tiers' plugin: its hooks act when pytest finds them here
    "pytest_addoption",
    "pytest_collection_finish",
    "pytest_collection_modifyitems",
    "pytest_collectreport",
    "pytest_make_collect_report",
    "pytest_runtest_logfinish",
    "pytest_runtest_logreport",
    "pytest_runtest_logstart",
    "pytest_runtest_makereport",
    "pytest_sessionfinish",
    "pytest_terminal_summary",
    "pytest_testnodedown",
]

REPO = Path(__file__).resolve().parents[1]
CONFIG_FILE = REPO / "config" / "mill.toml"


def pytest_configure(config: pytest.Config) -> None:
    """Started under a real-time policy (.ci/test's hil tiers): keep it for the service and node only.

    pytest itself goes back to the normal policy here, before it starts a thread of its own
    (tests/support/realtime.py). Under mutmut, a mutant is judged by its own module's tests
    (tests/support/mutation_tests.py). pytest-timeout's bound from pyproject.toml stretches with load
    (tests/support/timeouts.py). python-can's ``virtual`` bus is the one that copies frames
    without ``copy.deepcopy`` (tests/support/virtual_bus.py).
    """
    take_over()
    virtual_bus.install()
    config.pluginmanager.register(mutation_tests, "mutation_tests")
    config.pluginmanager.register(timeouts, "millctl_timeouts")


@pytest.hookimpl(wrapper=True)
def pytest_collection(session: pytest.Session) -> Generator[None, object, object]:
    """No cyclic collection while the tests are collected; then what the imports left is kept for good.

    A wrapper, so that the collector is switched on again however collection ends, and also in a
    pytest-xdist controller, which collects nothing (xdist answers this hook there) and never
    reaches ``pytest_collection_finish``.

    Importing the test modules (numba, scipy, textual, schemathesis…) leaves ~300 000 long-lived
    objects; each full collection during the tests would scan them all again (~0.15 s each, ~40 of
    them a run). Frozen, the collector only looks at what the tests make, and garbage the tests leave
    in reference cycles is found and finalized as before (so an unraisable exception still fails).
    """
    gc.disable()
    try:
        return (yield)
    finally:
        gc.collect()
        gc.freeze()
        gc.enable()


# Hypothesis refuses derandomize=True and a database in one settings(...) call ("derandomize=True implies
# database=None"), yet replays whatever database a settings object carries: the stored examples are added
# to a derandomized parent (tests/unit/support/test_stored_examples.py shows them replayed).
# No deadline in CI: Hypothesis' default (200 ms an example) is a timed assertion, and on the shared 2-core
# machine a correct example can wait longer than that for a core (test_limits.py's eq. 8a property failed
# so, "Test took 257.12ms", at load 5). The fuzz job keeps it, to point at examples that are slow.
settings.register_profile(
    "ci", settings(derandomize=True, print_blob=True, deadline=None), database=examples.replayed()
)
settings.register_profile(
    "fuzz",
    derandomize=False,
    max_examples=1000,
    database=examples.NewFailures(examples.stored()),
    phases=[phase for phase in Phase if phase is not Phase.reuse],
    print_blob=True,
)
settings.load_profile("ci")


@pytest.fixture(scope="session")
def config() -> MillConfig:
    """The repository's default configuration (parameter Set A)."""
    return load_config(CONFIG_FILE).config
