"""mutmut's verdicts kept in the repository, so that they outlive ``mutants/`` (docs/safety.md#mutation-testing).

mutmut 3 keeps each mutant's verdict (the exit code of its tests) only in
``mutants/<source>.py.meta``, beside ``hash_by_function_name``: a hash of each
mutated function's syntax tree. When it makes a file's mutants again it keeps a
verdict only if its function's hash is unchanged, so a function whose source
changed is judged again. ``mutants/`` is not in git, and a lost machine lost
every verdict.

``python -m tests.support.mutation_verdicts save`` copies the verdicts and the
hashes from ``mutants/`` into :data:`VERDICTS` (committed; one line a
function), merged with what the file held: a function whose hash in
``mutants/`` differs from the stored one has its stored verdicts dropped.
``restore`` writes them back into ``mutants/`` (``bash .ci/mutation`` does it
before each run): into a file's ``.meta`` where mutmut has none yet (and the
file's mutants are then made again, so that mutmut's own hash check runs), or
into the verdicts still missing from an existing one, for a function whose
hash there is the stored one. Either way mutmut compares the stored hash with
the function's source when it makes the mutants, and a changed function is
judged again, never trusted stale.

Stored with the verdicts: the mutmut version (another version mutates, and
numbers the mutants, differently) and the configuration that decides a
verdict (mutmut's own ``config_fingerprint``: pytest's arguments, the test
selection, the timeouts; and which tests judge which module,
tests/support/mutation_tests.py). ``restore`` restores nothing when either
differs, as mutmut resets every verdict when the test selection changes.
Only verdicts are kept (killed, timeout, survived); "no tests" and the rest
are mutmut's to give again, cheaply. What a function hash cannot see (a test
changed or removed since the verdict) it does not see here either, as it does
not in ``mutants/``.
"""

from __future__ import annotations

import hashlib
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tests.support.mutation_tests import MUTANT_TESTS

VERDICTS = Path("docs/mutation-verdicts.json")
"""The committed verdicts, from the repository root."""

KEPT = {0, 1, 3, 24, -24, 36, 152, 255}
"""The exit codes kept: survived (0), killed (1, 3) and timeout (mutmut.stats.status_by_exit_code)."""

FunctionVerdicts = dict[str, Any]
"""One function's entry: {"hash": mutmut's hash of its syntax tree, "verdicts": {mutant number: exit code}}."""


def setting() -> dict[str, object]:
    """What a verdict was given under: the mutmut version and the configuration that decides verdicts."""
    import mutmut
    from mutmut.configuration import config

    judges = hashlib.sha256(repr(sorted(MUTANT_TESTS.items())).encode()).hexdigest()[:12]
    return {"mutmut": mutmut.__version__, "config": {**config().config_fingerprint(), "judging_tests": judges}}


def _number(key: str) -> tuple[str, str]:
    """A mutant's full name → (its function's mangled name within the module, its number)."""
    function, separator, number = key.rpartition("__mutmut_")
    if not separator or not number.isdigit():
        raise ValueError(f"not a mutmut mutant name: {key!r}")
    return function.rpartition(".")[2], number


def read_meta(meta: Path) -> dict[str, Any]:
    """One ``.meta`` file of mutmut's (read again if mutmut was writing it)."""
    for _ in range(5):
        try:
            data: dict[str, Any] = json.loads(meta.read_text())
            return data
        except json.JSONDecodeError:
            continue
    raise ValueError(f"{meta}: not JSON (five reads); is mutmut writing it?")


def from_mutants(root: Path) -> dict[str, dict[str, FunctionVerdicts]]:
    """Source path → mangled function name → its hash and kept verdicts, from ``root`` (mutants/)."""
    files: dict[str, dict[str, FunctionVerdicts]] = {}
    for meta in sorted(root.rglob("*.py.meta")):
        data = read_meta(meta)
        hashes: dict[str, str] = data.get("hash_by_function_name", {})
        functions: dict[str, FunctionVerdicts] = {name: {"hash": h, "verdicts": {}} for name, h in hashes.items()}
        for key, code in data["exit_code_by_key"].items():
            function, number = _number(key)
            if code in KEPT and function in functions:
                functions[function]["verdicts"][number] = code
        if functions:
            files[meta.relative_to(root).with_suffix("").as_posix()] = functions
    return files


def merge(
    stored: dict[str, dict[str, FunctionVerdicts]], fresh: dict[str, dict[str, FunctionVerdicts]]
) -> dict[str, dict[str, FunctionVerdicts]]:
    """``fresh`` over ``stored``: a stored function keeps its verdicts only while its hash is the fresh one."""
    merged = {path: dict(functions) for path, functions in stored.items()}
    for path, functions in fresh.items():
        into = merged.setdefault(path, {})
        for name, entry in functions.items():
            old = into.get(name)
            verdicts = dict(old["verdicts"]) if old is not None and old["hash"] == entry["hash"] else {}
            verdicts.update(entry["verdicts"])
            into[name] = {"hash": entry["hash"], "verdicts": verdicts}
    return merged


def load(path: Path) -> dict[str, Any] | None:
    """The stored verdicts file, or None if there is none."""
    if not path.is_file():
        return None
    data: dict[str, Any] = json.loads(path.read_text())
    for field in ("setting", "files"):
        if field not in data:
            raise ValueError(f"{path}: no {field!r} (written by `python -m tests.support.mutation_verdicts save`?)")
    return data


def dump(path: Path, current: dict[str, object], files: dict[str, dict[str, FunctionVerdicts]]) -> None:
    """Write the verdicts file: one line a function, sorted, so that a diff shows which functions changed."""
    lines = ["{", f' "setting": {json.dumps(current, sort_keys=True, ensure_ascii=False)},', ' "files": {']
    paths = sorted(path for path, functions in files.items() if any(e["verdicts"] for e in functions.values()))
    for i, source in enumerate(paths):
        names = sorted(name for name, entry in files[source].items() if entry["verdicts"])
        lines.append(f"  {json.dumps(source)}: {{")
        for j, name in enumerate(names):
            entry = files[source][name]
            verdicts = {n: entry["verdicts"][n] for n in sorted(entry["verdicts"], key=int)}
            body = json.dumps({"hash": entry["hash"], "verdicts": verdicts}, separators=(", ", ": "))
            lines.append(f"   {json.dumps(name, ensure_ascii=False)}: {body}{',' if j < len(names) - 1 else ''}")
        lines.append(f"  }}{',' if i < len(paths) - 1 else ''}")
    lines += [" }", "}"]
    path.write_text("\n".join(lines) + "\n")


def save(root: Path, path: Path, current: dict[str, object]) -> int:
    """Merge the verdicts in ``root`` into ``path``; the number of verdicts the file then holds."""
    stored = load(path)
    kept = stored["files"] if stored is not None and stored["setting"] == current else {}
    files = merge(kept, from_mutants(root))
    dump(path, current, files)
    return sum(len(entry["verdicts"]) for functions in files.values() for entry in functions.values())


def restore(root: Path, path: Path, current: dict[str, object]) -> int:
    """Write the stored verdicts into ``root``'s ``.meta`` files where mutmut has none; the number written.

    mutmut's own hash check, when it next makes the mutants, then drops those of a changed function.
    """
    stored = load(path)
    if stored is None:
        return 0
    from mutmut.utils.format_utils import get_mutant_name

    if stored["setting"] != current:
        print(
            f"{path}: given under {stored['setting']}, not the current {current}; restored nothing "
            "(every mutant is judged again)",
            file=sys.stderr,
        )
        return 0
    written = 0
    for source, functions in stored["files"].items():
        meta = root / f"{source}.meta"
        made = meta.is_file()
        if made:
            data = read_meta(meta)
        else:
            # no .meta: mutmut makes this file's mutants afresh and checks the stored hashes against its source
            (root / source).unlink(missing_ok=True)
            meta.parent.mkdir(parents=True, exist_ok=True)
            data = {
                "exit_code_by_key": {},
                "hash_by_function_name": {name: entry["hash"] for name, entry in functions.items()},
                "type_check_error_by_key": {},
                "durations_by_key": {},
                "estimated_durations_by_key": {},
            }
        hashes: dict[str, str] = data["hash_by_function_name"]
        codes: dict[str, int | None] = data["exit_code_by_key"]
        for name, entry in functions.items():
            if hashes.get(name) != entry["hash"]:
                continue  # mutants/ holds another version of this function (or none): its own verdicts stand
            for number, code in entry["verdicts"].items():
                key = get_mutant_name(Path(source), f"{name}__mutmut_{number}")
                if (key in codes or not made) and codes.get(key) is None:
                    codes[key] = code
                    written += 1
        meta.write_text(json.dumps(data, indent=4, ensure_ascii=False))
    return written


def main(argv: Sequence[str]) -> int:
    if len(argv) != 1 or argv[0] not in ("save", "restore"):
        print("usage: python -m tests.support.mutation_verdicts save|restore", file=sys.stderr)
        return 1
    root = Path("mutants")
    if argv[0] == "save":
        if not root.is_dir():
            print("error: no mutants/ here: nothing to save (run `bash .ci/mutation` first)", file=sys.stderr)
            return 2
        count = save(root, VERDICTS, setting())
        print(f"{VERDICTS}: {count} verdicts", file=sys.stderr)
    else:
        count = restore(root, VERDICTS, setting())
        print(f"restored {count} verdicts from {VERDICTS} into {root}/", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
