"""Which unit tests judge a mutant: the tests of its own module (mutation testing, docs/safety.md#mutation-testing).

mutmut runs, for each mutant, every test in ``[tool.mutmut]``'s selection that
reached the mutated function in its stats run. The envelope, the ramp planner,
the wire rounding, the E2E protection and the node's link monitor are reached
by nearly every test of the node and the controller (each builds an envelope
and talks E2E), so one
surviving mutant there cost the whole selection, 1–2 min on the shared
machine. Under mutmut (``MUTANT_UNDER_TEST`` names a mutant) this plugin keeps
only the tests written for the mutant's module (:data:`MUTANT_TESTS`): a
mutant there is judged by its module's own unit tests, which is what a
survivor should make stronger. Modules not listed keep every test that
reaches them. ``MUTMUT_ALL_TESTS=1`` turns the restriction off (to measure
it, or to ask whether any test at all kills a survivor). Outside mutmut it does
nothing.
"""

from __future__ import annotations

import os
import re

import pytest

MUTANT_TESTS: dict[str, tuple[str, ...]] = {
    # the envelope's own tests and the ramp planner's, whose property tests hold every planned point to it
    "millctl.safety.envelope": ("tests/unit/test_envelope.py", "tests/unit/test_ramps.py"),
    "millctl.safety.ramps": ("tests/unit/test_ramps.py",),
    "millctl.safety.wire": ("tests/unit/test_ramps.py",),
    "millctl.safety.slew": ("tests/unit/test_slew.py",),
    "millctl.protocol.e2e": ("tests/unit/protocol/test_e2e.py",),
    "firmware_sim.monitor": ("tests/unit/node/test_monitor.py",),
    # the link monitor on its own and the challenge's rules; every node test talks E2E and feeds the watchdog
    "firmware_sim.link": ("tests/unit/node/test_link.py", "tests/unit/node/test_heartbeat_challenge.py"),
}
"""Mutated module → the test files (paths from the repository root) that judge its mutants."""

_MODULE = re.compile(r"^(?P<module>[\w.]+?)\.x[_ǁ]")
"""A mutant's name is ``module.x_function__mutmut_N`` or ``module.xǁClassǁmethod__mutmut_N``."""


def judging_tests(mutant: str) -> tuple[str, ...] | None:
    """The test files that judge ``mutant`` (None: every test that reaches it)."""
    match = _MODULE.match(mutant)
    return MUTANT_TESTS.get(match["module"]) if match else None


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Under mutmut, deselect the tests that are not the mutated module's own."""
    mutant = os.environ.get("MUTANT_UNDER_TEST", "")
    all_tests = os.environ.get("MUTMUT_ALL_TESTS", "0") == "1"
    owners = judging_tests(mutant) if "__mutmut_" in mutant and not all_tests else None
    if owners is None:
        return
    kept = [item for item in items if item.nodeid.startswith(owners)]
    dropped = [item for item in items if not item.nodeid.startswith(owners)]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = kept
