"""The classification of mutmut's survivors by what their mutation changes (tests/support/mutation_survivors.py)."""

from __future__ import annotations

import pytest

from tests.support.mutation_survivors import FALSY_PENDING, OTHER, WORDING, changed_lines, classify, function_of

ORIGINAL = """
def f(self, now):
    log.debug("sent %s at %s", self.code, now)
    self._reset_pending = False
    if now > self.deadline_s:
        raise ValueError(f"late by {now - self.deadline_s}")
    self._trip("overrun", "controller")
"""


@pytest.mark.parametrize(
    ("old", "new", "kind"),
    [
        ('"sent %s at %s", self.code, now', "None, self.code, now", WORDING),
        ('"sent %s at %s", self.code, now', '"sent %s at %s", self.code', WORDING),
        ('raise ValueError(f"late by {now - self.deadline_s}")', "raise ValueError(None)", WORDING),
        ('"overrun", "controller"', '"XXoverrunXX", "controller"', WORDING),
        ("self._reset_pending = False", "self._reset_pending = None", FALSY_PENDING),
        ("self._reset_pending = False", "self._reset_pending = True", OTHER),
        ("now > self.deadline_s:", "now >= self.deadline_s:", OTHER),
        ('"overrun", "controller"', '"overrun", None', OTHER),
    ],
)
def test_each_mutation_is_classified_by_what_it_changes(old: str, new: str, kind: str) -> None:
    assert old in ORIGINAL
    assert classify(ORIGINAL, ORIGINAL.replace(old, new, 1)) == kind


def test_a_mutant_changing_wording_and_logic_at_once_is_other() -> None:
    mutant = ORIGINAL.replace('"overrun"', '"XXoverrunXX"').replace("now > ", "now >= ")
    assert classify(ORIGINAL, mutant) == OTHER


def test_a_mutant_equal_to_its_original_is_an_error() -> None:
    with pytest.raises(ValueError, match="the original"):
        classify(ORIGINAL, ORIGINAL)


def test_names_and_diff_lines() -> None:
    assert (
        function_of("millctl.controller.confirm.xǁConfirmationsǁdue__mutmut_3")
        == "millctl.controller.confirm.Confirmations.due"
    )
    assert function_of("millctl.safety.wire.x__crossings__mutmut_17") == "millctl.safety.wire._crossings"
    diff = "--- a.py\n+++ a.py\n@@ -1,2 +1,2 @@\n-    x = 1\n+    x  =  2\n     y = 3"
    assert changed_lines(diff) == "-x = 1 ~ +x = 2"
