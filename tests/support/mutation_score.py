"""The mutation score kept in ``mutants/`` by mutmut (``bash .ci/mutation``), whole scope and per module.

``python -m tests.support.mutation_score [GLOB ...]`` reads mutmut's verdicts
(``mutants/**/*.py.meta``, one exit code per mutant) and prints one line per
module and one for the whole scope: killed (a test failed, or timed out) of
the mutants tested, survivors, mutants no test reaches and mutants not yet
run; then every survivor by name (``mutmut show NAME`` shows its diff). With
globs, only the mutants whose names match count. ``--not-run [GLOB ...]``
prints only the names of the matching mutants with no verdict yet, one a line,
for ``bash .ci/mutation`` to test them in the order given. ``--cost [GLOB ...]``
prints, per module, what a surviving mutant costs in tests (the test durations
mutmut's stats run measured, summed over the tests that reach the mutated
function): with every such test, and with only those that judge it
(tests/support/mutation_tests.py). Reads only.
"""

from __future__ import annotations

import fnmatch
import json
import sys
from collections import Counter
from collections.abc import Iterable, Sequence
from pathlib import Path

from tests.support.mutation_tests import judging_tests

KILLED = {1: "killed", 3: "killed", 36: "timeout", -24: "timeout", 24: "timeout", 152: "timeout", 255: "timeout"}
"""mutmut's exit codes that mean a test caught the mutant (mutmut.stats.status_by_exit_code); a timeout
counts as killed, as mutmut counts it, and is shown apart."""
SURVIVED = 0
NO_TESTS = {5, 33}
NOT_RUN = None


def verdicts(root: Path, globs: Sequence[str]) -> dict[str, dict[str, int | None]]:
    """Module name → {mutant name → exit code (None: not run yet)}, for the mutants matching ``globs``."""
    by_module: dict[str, dict[str, int | None]] = {}
    for meta in sorted(root.rglob("*.py.meta")):
        codes: dict[str, int | None] = json.loads(meta.read_text())["exit_code_by_key"]
        chosen = {
            name: code for name, code in codes.items() if not globs or any(fnmatch.fnmatch(name, g) for g in globs)
        }
        if chosen:
            module = ".".join(meta.relative_to(root).with_suffix("").with_suffix("").parts)
            by_module[module] = chosen
    return by_module


def verdict(code: int | None) -> str:
    """mutmut's exit code of one mutant as a verdict: killed, survived, no tests, not run or other."""
    if code in KILLED:
        return KILLED[code]
    if code == SURVIVED:
        return "survived"
    if code in NO_TESTS:
        return "no tests"
    return "not run" if code is NOT_RUN else "other"


def score_line(label: str, codes: Iterable[int | None]) -> str:
    """One score line: killed/tested (%), survived, no tests, not run, other (suspicious, skipped, segfault)."""
    counts = Counter(verdict(code) for code in codes)
    killed = counts["killed"] + counts["timeout"]
    tested = killed + counts["survived"] + counts["other"]
    percent = 100.0 * killed / tested if tested else 0.0
    timeouts = f" (timeout {counts['timeout']})" if counts["timeout"] else ""
    return (
        f"{label}: {killed}/{tested} killed{timeouts} ({percent:.1f} %); survived {counts['survived']}, "
        f"no test {counts['no tests']}, not run {counts['not run']}, other {counts['other']}, "
        f"total {sum(counts.values())}"
    )


def survivor_cost_s(
    tests_by_function: dict[str, list[str]], durations: dict[str, float], mutant: str
) -> tuple[float, float]:
    """Seconds of tests a surviving ``mutant`` costs: every test that reaches it, and those that judge it."""
    tests = tests_by_function.get(mutant.rsplit("__mutmut_", 1)[0], [])
    judges = judging_tests(mutant)
    every = sum(durations.get(test, 0.0) for test in tests)
    judged = every if judges is None else sum(durations.get(test, 0.0) for test in tests if test.startswith(judges))
    return every, judged


def print_cost(root: Path, by_module: dict[str, dict[str, int | None]]) -> None:
    stats = json.loads((root / "mutmut-stats.json").read_text())
    for module, codes in by_module.items():
        costs = [survivor_cost_s(stats["tests_by_mangled_function_name"], stats["duration_by_test"], n) for n in codes]
        every = sum(cost[0] for cost in costs) / len(costs)
        judged = sum(cost[1] for cost in costs) / len(costs)
        print(f"  {module}: a survivor costs {every:.1f} s of tests, {judged:.1f} s of those that judge it")


def main(argv: Sequence[str]) -> int:
    not_run_only = bool(argv) and argv[0] == "--not-run"
    cost_only = bool(argv) and argv[0] == "--cost"
    if not_run_only or cost_only:
        argv = argv[1:]
    root = Path("mutants")
    if not root.is_dir():
        print(
            "error: no mutants/ here: run `bash .ci/mutation` first (docs/safety.md#mutation-testing)", file=sys.stderr
        )
        return 2
    by_module = verdicts(root, argv)
    if not by_module:
        print(f"error: no mutant in mutants/ matches {' '.join(argv)!r}", file=sys.stderr)
        return 2
    if cost_only:
        print_cost(root, by_module)
        return 0
    if not_run_only:
        for codes in by_module.values():
            for name, code in codes.items():
                if code is NOT_RUN:
                    print(name)
        return 0
    for module, codes in by_module.items():
        print(score_line(f"  {module}", codes.values()))
    every = [code for codes in by_module.values() for code in codes.values()]
    print(score_line("mutation score", every))
    print("surviving mutants:")
    for codes in by_module.values():
        for name, code in codes.items():
            if code == SURVIVED:
                print(f"  {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
