"""The stored examples: what the random search found, committed, and replayed by every CI run.

Two kinds of stored example, both replayed by the derandomized ``ci`` profile every run:

* **Hand-picked hard cases** are explicit: ``@example(...)`` on a Hypothesis test, or a case built
  from the schema for the API fuzzer (tests/unit/service/test_schema.py). They are code: reviewed,
  and they survive any edit of the test.
* **Failures the random search found** (``bash .ci/fuzz``) are kept in :data:`EXAMPLES_DIR`, a
  Hypothesis ``DirectoryBasedExampleDatabase`` under version control. The fuzz job writes the
  minimal failing example of each bug it finds there (:class:`NewFailures`); commit it with the fix.
  CI reads it through a ``ReadOnlyDatabase``: replayed first, never changed.

Hypothesis refuses ``derandomize=True`` together with a database in one ``settings(...)`` call
("derandomize=True implies database=None"): a derandomized run repeats its own examples, so it keeps
none. Its engine replays whatever database the settings carry, so the ``ci`` profile derives from a
derandomized parent and adds the stored database (tests/conftest.py);
tests/unit/support/test_stored_examples.py shows a stored example replayed under it.

Hypothesis keys an entry by a digest of its test's source (decorators and comments left out): an edit
to a test's body orphans its stored entries. :func:`orphaned_keys` finds them, and the unit tier fails
on one (turn it into an ``@example``, which the fuzz job's report prints, or run the fuzz job again).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from types import ModuleType

from hypothesis.database import (
    DirectoryBasedExampleDatabase,
    ExampleDatabase,
    ReadOnlyDatabase,
    choices_from_bytes,
)
from hypothesis.internal.reflection import function_digest

REPO = Path(__file__).resolve().parents[2]
EXAMPLES_DIR = REPO / "tests" / "examples" / "hypothesis"
"""The committed example database (one folder a key, one file a stored example)."""

METAKEYS = b".hypothesis-keys"
"""The key under which a DirectoryBasedExampleDatabase lists every key it holds."""

SUB_KEYS = (b"secondary", b"pareto")
"""Hypothesis's own sub-corpora of a key (non-minimal failures, targeting's front): not worth keeping."""


def stored() -> DirectoryBasedExampleDatabase:
    """The committed example database, writable (the fuzz job writes through :class:`NewFailures`)."""
    return DirectoryBasedExampleDatabase(EXAMPLES_DIR)


def replayed() -> ReadOnlyDatabase:
    """The committed example database as CI reads it: every entry replayed, none saved, moved or deleted."""
    return ReadOnlyDatabase(stored())


class NewFailures(ExampleDatabase):
    """The fuzz job's writer: the minimal failing example of each new bug, and nothing else.

    Hypothesis keeps a shrink's larger failures in a ``.secondary`` sub-key and a targeting front in
    ``.pareto``: they are dropped, so that what the fuzz job leaves in the committed folder is one
    small file a bug. Deletions pass through: a shrink replaces its larger failure by the smaller one.
    The fuzz profile also leaves out Hypothesis's replay phase, so an entry that passes again after its
    fix is never deleted: it stays a regression example (CI replays the stored examples every run).
    """

    def __init__(self, db: ExampleDatabase) -> None:
        super().__init__()
        self._wrapped = db

    def __repr__(self) -> str:
        return f"NewFailures({self._wrapped!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, NewFailures) and self._wrapped == other._wrapped

    def __hash__(self) -> int:
        return hash(("NewFailures", repr(self._wrapped)))

    def fetch(self, key: bytes) -> Iterable[bytes]:
        yield from self._wrapped.fetch(key)

    def save(self, key: bytes, value: bytes) -> None:
        if not key.endswith(tuple(b"." + sub for sub in SUB_KEYS)):
            self._wrapped.save(key, value)

    def delete(self, key: bytes, value: bytes) -> None:
        self._wrapped.delete(key, value)


def inner_test(test: Callable[..., object]) -> Callable[..., object]:
    """The function Hypothesis runs for a ``@given`` test (its digest keys the test's stored examples)."""
    inner: Callable[..., object] | None = getattr(getattr(test, "hypothesis", None), "inner_test", None)
    if inner is None:
        raise TypeError(f"{test!r} is not a Hypothesis test (no .hypothesis.inner_test)")
    return inner


def hypothesis_tests(package: str = "tests.unit") -> Iterator[tuple[str, Callable[..., object]]]:
    """Every Hypothesis test of the package's test modules, as (``module::name``, the test Hypothesis runs).

    The test Hypothesis runs is the ``inner_test`` of a ``@given`` test (and of a schemathesis one, which
    hands its undecorated function to Hypothesis): its digest is the key of its stored examples.
    """
    for module in _test_modules(package):
        for name, obj in vars(module).items():
            if not name.startswith("test_") or not callable(obj):
                continue
            if getattr(getattr(obj, "hypothesis", None), "inner_test", None) is not None:
                yield f"{module.__name__}::{name}", inner_test(obj)


def stored_choices(test: Callable[..., object], db: ExampleDatabase | None = None) -> list[tuple[object, ...]]:
    """The stored examples of the test Hypothesis runs (an ``inner_test``), decoded: one tuple of choices each."""
    entries = (db or stored()).fetch(function_digest(test))
    return [tuple(choices) for choices in map(choices_from_bytes, entries) if choices is not None]


def orphaned_keys(db: DirectoryBasedExampleDatabase, package: str = "tests.unit") -> list[Path]:
    """The folders of ``db`` that no Hypothesis test of the package reads: their examples replay nowhere."""
    read = set()
    for _, test in hypothesis_tests(package):
        digest = function_digest(test)
        for key in (digest, *(b".".join((digest, sub)) for sub in SUB_KEYS)):
            read.add(db._key_path(key).name)  # the database's own mapping of a key to its folder
    read.add(db._key_path(METAKEYS).name)  # the database's index of its own keys
    folders = [p for p in db.path.iterdir() if p.is_dir()] if db.path.is_dir() else []
    return sorted(p for p in folders if p.name not in read)


def _test_modules(package: str) -> Iterator[ModuleType]:
    root = importlib.import_module(package)
    for info in pkgutil.walk_packages(root.__path__, prefix=f"{package}."):
        if info.name.rpartition(".")[2].startswith("test_"):
            yield importlib.import_module(info.name)
