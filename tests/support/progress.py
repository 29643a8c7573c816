"""How far a pytest run got before it was cut, from its progress log (``$MILLCTL_PROGRESS_LOG``).

The CI tiers' plugin (tests/support/tiers.py) appends to that log as the run goes: ``collected N``
once, then ``start HH:MM:SS NODEID`` as each test starts and ``OUTCOME HH:MM:SS NODEID`` as it ends.
A run stopped from outside (the VM's timeout in ``tests/vm/run``) prints no summary of its own, so

    python -m tests.support.progress TIER LOG WHY

prints the tier's closing line for it, e.g. ``vcan: FAILED: cut (timeout 4176 s) after 23 of 32
cases: 23 passed, 0 failed, 0 errors, 0 skipped; in tests/hil/test_stop_race.py::test_x[socketcan];
8 not started``, which ``.ci/run`` prints with the other tiers' lines.
"""

from __future__ import annotations

import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

OUTCOMES = ("passed", "failed", "error", "skipped", "xfailed", "xpassed")
"""What a test can end as in the log (tests/support/tiers.py, ``outcome_after``)."""


class ProgressLogError(ValueError):
    """A line of the progress log that is none of its three kinds."""


@dataclass(frozen=True)
class Progress:
    """What the log says: tests collected, outcomes so far, and the test that started and never ended."""

    collected: int | None
    outcomes: Counter[str] = field(default_factory=Counter)
    running: str | None = None

    @property
    def finished(self) -> int:
        return sum(self.outcomes.values())


def read_progress(text: str, source: str = "the progress log") -> Progress:
    """Parse a progress log; a line it does not know raises :class:`ProgressLogError` naming it."""
    collected: int | None = None
    outcomes: Counter[str] = Counter()
    running: str | None = None
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        word, _, rest = line.partition(" ")
        if word == "collected" and rest.strip().isdigit():
            collected = int(rest)
            continue
        _stamp, _, nodeid = rest.partition(" ")
        if not nodeid:
            raise ProgressLogError(f"{source}, line {number}: {line!r} is not 'collected N' or 'WORD HH:MM:SS NODEID'")
        if word == "start":
            running = nodeid
        elif word in OUTCOMES:
            outcomes[word] += 1
            if running == nodeid:
                running = None
        else:
            raise ProgressLogError(
                f"{source}, line {number}: unknown word {word!r} (expected 'collected', 'start' or one of {OUTCOMES})"
            )
    return Progress(collected, outcomes, running)


def cut_line(tier: str, progress: Progress, why: str) -> str:
    """The closing line of a tier whose run was cut: how far it got, what it was in, what never started."""
    head = f"{tier}: FAILED: cut ({why})"
    if progress.collected is None:
        return f"{head} before pytest had collected its tests"
    n = progress.outcomes
    counts = f"{n['passed']} passed, {n['failed']} failed, {n['error']} errors, {n['skipped']} skipped"
    extras = [f"{n[key]} {key}" for key in ("xfailed", "xpassed") if n[key]]
    line = f"{head} after {progress.finished} of {progress.collected} cases: {counts}"
    line += f" ({', '.join(extras)})" if extras else ""
    if progress.running is not None:
        line += f"; in {progress.running}"
    not_started = progress.collected - progress.finished - (progress.running is not None)
    return line + f"; {max(not_started, 0)} not started"


def main(argv: list[str]) -> int:
    """``python -m tests.support.progress TIER LOG WHY``: print the cut run's closing line."""
    if len(argv) != 3:
        print("usage: python -m tests.support.progress TIER LOG WHY", file=sys.stderr)
        return 2
    tier, log, why = argv
    path = Path(log)
    try:
        text = path.read_text(encoding="utf-8") if path.exists() else ""
        print(cut_line(tier, read_progress(text, str(path)), why))
    except (OSError, UnicodeDecodeError, ProgressLogError) as exc:
        print(f"progress: error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))


__all__ = ["OUTCOMES", "Progress", "ProgressLogError", "cut_line", "main", "read_progress"]
