"""The stored examples (tests/support/examples.py): CI replays them read-only, the fuzz job adds to them.

Issue 14 item 1: CI must be deterministic (a fixed seed and a stored example database) with the random
search in a separate, longer job. The replay itself is shown on a real stored example, the NUL-byte
recipe name (tests/unit/service/test_schema.py::test_the_stored_nul_byte_name_is_replayed_every_run).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st
from hypothesis.database import (
    DirectoryBasedExampleDatabase,
    InMemoryExampleDatabase,
    ReadOnlyDatabase,
    choices_to_bytes,
)
from hypothesis.errors import InvalidArgument
from hypothesis.internal.reflection import function_digest

from tests.support import examples


def test_the_ci_profile_is_derandomized_and_reads_the_committed_examples_only() -> None:
    ci = settings.get_profile("ci")
    assert ci.derandomize
    assert ci.database == ReadOnlyDatabase(DirectoryBasedExampleDatabase(examples.EXAMPLES_DIR))
    assert Phase.reuse in ci.phases and Phase.explicit in ci.phases
    assert ci.deadline is None  # a timed assertion: a loaded CI machine failed a correct example on it


def test_the_fuzz_profile_searches_afresh_and_writes_new_failures_to_the_committed_examples() -> None:
    fuzz = settings.get_profile("fuzz")
    assert not fuzz.derandomize and fuzz.max_examples >= 1000
    assert fuzz.database == examples.NewFailures(DirectoryBasedExampleDatabase(examples.EXAMPLES_DIR))
    assert Phase.reuse not in fuzz.phases  # so it never deletes a stored example that passes again


def test_hypothesis_refuses_derandomize_with_a_database_in_one_call() -> None:
    """Why the ci profile adds the database to a derandomized parent (and schemathesis tests set none)."""
    with pytest.raises(InvalidArgument, match="derandomize=True implies database=None"):
        settings(derandomize=True, database=InMemoryExampleDatabase())


def test_a_derandomized_run_replays_a_stored_failure_first(tmp_path: Path) -> None:
    """The ci profile's construction, on a database of our own: the stored failing input is tried first
    (the derandomized search alone would not draw it) and fails the test."""
    db = DirectoryBasedExampleDatabase(tmp_path)
    seen: list[int] = []

    def fails_on_one_value(n: int) -> None:
        seen.append(n)
        assert n != 123_456_789

    db.save(function_digest(fails_on_one_value), choices_to_bytes((123_456_789,)))
    test = settings(settings(derandomize=True), database=ReadOnlyDatabase(db), max_examples=5)(
        given(st.integers())(fails_on_one_value)
    )
    with pytest.raises(AssertionError):
        test()
    assert seen[0] == 123_456_789
    assert examples.stored_choices(fails_on_one_value, db) == [(123_456_789,)]  # read only: nothing added


def test_new_failures_keeps_the_minimal_failure_and_drops_hypothesis_sub_corpora() -> None:
    memory = InMemoryExampleDatabase()
    db = examples.NewFailures(memory)
    key = b"k" * 48
    db.save(key, b"big")
    db.move(key, key + b".secondary", b"big")  # a shrink: the larger failure leaves the primary key
    db.save(key, b"small")
    db.save(key + b".pareto", b"front")
    assert set(memory.fetch(key)) == {b"small"}
    assert not list(memory.fetch(key + b".secondary")) and not list(memory.fetch(key + b".pareto"))


def test_every_stored_example_belongs_to_a_test_of_the_unit_tier() -> None:
    """An edit to a test's body changes the key of its stored examples: they would silently replay nowhere."""
    orphans = examples.orphaned_keys(examples.stored())
    assert not orphans, (
        f"stored examples that no Hypothesis test of tests/unit reads (its body changed?): {orphans}; "
        "write them as @example(...) (the fuzz job's report names each), or find them again with .ci/fuzz"
    )


def test_an_orphaned_key_is_found(tmp_path: Path) -> None:
    db = DirectoryBasedExampleDatabase(tmp_path)
    db.save(b"no test has this digest", b"\x00")
    assert len(examples.orphaned_keys(db)) == 1
