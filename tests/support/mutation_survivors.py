"""mutmut's surviving mutants, each classified by what its mutation changes (docs/safety.md#mutation-testing).

``python -m tests.support.mutation_survivors [GLOB ...]`` reads the survivors
kept in ``mutants/`` (as ``bash .ci/mutation-score`` does), compares each
mutant's function with the original (as ``mutmut show`` does, on their syntax
trees) and prints a table, one row a function: its survivors, how many only
change wording (a string literal for another, or anything inside the
arguments of a log call or of a raised exception), how many put ``None`` for
``False`` in a ``*_pending`` flag (falsy, read only for its truth), and how
many change anything else; then every one of the others by name with the
lines its diff changes, to be judged by a reader. Reads only.
"""

from __future__ import annotations

import ast
import sys
from collections import Counter
from collections.abc import Iterator, Sequence
from pathlib import Path

from tests.support.mutation_score import SURVIVED, verdicts

WORDING = "wording"
FALSY_PENDING = "falsy None"
OTHER = "other"
LOG_METHODS = {"debug", "info", "warning", "error", "exception", "critical", "log"}


def _is_log_call(node: ast.AST) -> bool:
    """``log.debug(…)``, ``self._log.info(…)``: a call of a logging method on something named like a logger."""
    if not isinstance(node, ast.Call) or not isinstance(node.func, ast.Attribute):
        return False
    base = node.func.value
    name = base.id if isinstance(base, ast.Name) else base.attr if isinstance(base, ast.Attribute) else ""
    return node.func.attr in LOG_METHODS and "log" in name.lower()


def _same(a: object, b: object) -> bool:
    if isinstance(a, ast.AST) and isinstance(b, ast.AST):
        return ast.dump(a) == ast.dump(b)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b


def differences(
    a: object, b: object, path: tuple[ast.AST, ...] = ()
) -> Iterator[tuple[tuple[ast.AST, ...], object, object]]:
    """The smallest differing parts of two syntax trees: (the nodes above, the part in ``a``, the part in ``b``)."""
    if isinstance(a, ast.AST) and type(a) is type(b):
        for field in a._fields:
            va, vb = getattr(a, field, None), getattr(b, field, None)
            if _same(va, vb):
                continue
            if isinstance(va, list) and isinstance(vb, list) and len(va) == len(vb):
                for x, y in zip(va, vb, strict=True):
                    if not _same(x, y):
                        yield from differences(x, y, (*path, a))
            elif isinstance(va, ast.AST) and isinstance(vb, ast.AST):
                yield from differences(va, vb, (*path, a))
            else:
                yield (*path, a), va, vb
    elif not _same(a, b):
        yield path, a, b


def _is_str(node: object) -> bool:
    return isinstance(node, ast.Constant) and isinstance(node.value, str)


def _is_falsy_pending(path: tuple[ast.AST, ...], a: object, b: object) -> bool:
    """``self._x_pending = None`` for ``= False``."""
    if isinstance(a, ast.Constant) and isinstance(b, ast.Constant):
        a, b = a.value, b.value
    elif path and isinstance(path[-1], ast.Constant):
        path = path[:-1]
    if not (a is False and b is None):
        return False
    assign = path[-1] if path else None
    return isinstance(assign, ast.Assign) and all(
        isinstance(t, ast.Attribute) and t.attr.endswith("_pending") for t in assign.targets
    )


def classify(original: str, mutant: str) -> str:
    """What a mutation changes: :data:`WORDING`, :data:`FALSY_PENDING` or :data:`OTHER`."""
    kinds = set()
    found = False
    for path, a, b in differences(ast.parse(original), ast.parse(mutant)):
        found = True
        above = (*path, a) if isinstance(a, ast.AST) else path
        in_text = any(_is_log_call(n) or isinstance(n, ast.Raise) for n in above)
        strings = (_is_str(a) and _is_str(b)) or (
            bool(path) and isinstance(path[-1], ast.Constant) and isinstance(a, str) and isinstance(b, str)
        )
        if in_text or strings:
            kinds.add(WORDING)
        elif _is_falsy_pending(path, a, b):
            kinds.add(FALSY_PENDING)
        else:
            kinds.add(OTHER)
    if not found:
        raise ValueError("the mutant's function is the original's")
    return kinds.pop() if len(kinds) == 1 else OTHER


def changed_lines(diff: str) -> str:
    """The lines a unified diff takes out and puts in, ``-old ~ +new``."""
    lines = [line for line in diff.splitlines()[2:] if line[:1] in "+-"]
    return " ~ ".join(line[0] + " ".join(line[1:].split()) for line in lines)


def function_of(mutant: str) -> str:
    """``pkg.mod.xǁClassǁmethod__mutmut_3`` → ``pkg.mod.Class.method``; ``pkg.mod.x_f__mutmut_3`` → ``pkg.mod.f``."""
    module, _, mangled = mutant.rpartition("__mutmut_")[0].rpartition(".")
    name = ".".join(mangled.split("ǁ")[1:]) if mangled.startswith("xǁ") else mangled.removeprefix("x_")
    return f"{module}.{name}"


def main(argv: Sequence[str]) -> int:
    import libcst as cst
    from mutmut.mutation.diff_apply import (
        get_diff_for_mutant,
        read_functions_from_index,
        read_mutant_function,
        read_mutants_module,
        read_original_function,
    )

    root = Path("mutants")
    if not root.is_dir():
        print(
            "error: no mutants/ here: run `bash .ci/mutation` first (docs/safety.md#mutation-testing)", file=sys.stderr
        )
        return 2
    rows: dict[str, Counter[str]] = {}
    others: list[tuple[str, str]] = []
    for module, codes in verdicts(root, argv).items():
        path = Path(*module.split(".")).with_suffix(".py")
        parsed = None
        for name, code in codes.items():
            if code != SURVIVED:
                continue
            functions = read_functions_from_index(name, path)
            if functions is None:
                parsed = parsed or read_mutants_module(path)
                functions = (read_original_function(parsed, name), read_mutant_function(parsed, name))
            original, mutant = (cst.Module([f]).code for f in functions)
            kind = classify(original, mutant)
            rows.setdefault(function_of(name), Counter())[kind] += 1
            if kind == OTHER:
                others.append((name, changed_lines(get_diff_for_mutant(name, path=path))))
    print(f"| function | survivors | {WORDING} | {FALSY_PENDING} | {OTHER} |")
    print("|---|---|---|---|---|")
    for function, counts in rows.items():
        print(
            f"| `{function}` | {sum(counts.values())} | {counts[WORDING]} | {counts[FALSY_PENDING]} | {counts[OTHER]} |"
        )
    total = Counter[str]()
    for counts in rows.values():
        total.update(counts)
    print(f"| all | {sum(total.values())} | {total[WORDING]} | {total[FALSY_PENDING]} | {total[OTHER]} |")
    print(f"{OTHER}:")
    for name, lines in others:
        print(f"  {name}: {lines}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
