"""``python -m bench.startup``: how long millctl takes to start and to refuse a bad file, against ``python -c pass``.

Each case is the real CLI in a fresh interpreter (``python -m millctl …``), run
``--repeat`` times interleaved with the baseline ``python -c pass`` so that both
see the same load; the table gives the median wall time and the median CPU time
(user + system, from the child's resource usage) of each, and the ratio to the
baseline measured in the same run. The refusals (``/dev/zero``, a FIFO, nested
TOML; issue 37 item 5, docs/safety.md) must exit 1; the client commands run
against a socket where no service listens and must exit 3. No figure here is a
pass/fail bound: the tests assert what was imported, this prints what it cost.

``--processes`` adds what the mill's long-running processes import before they
do anything (issue 36, part 5: every hil and VM test starts them): ``millctl
serve``'s service, ``python -m firmware_sim`` for the millbus node and for the
CiA 402 drives, each as ``python -c "import …"`` of the modules that process loads.

``--compare DIR`` runs every case once more from another source tree (e.g.
``git worktree add /tmp/old main``), interleaved too, and prints its figures
beside these: a before/after from one run, under one load.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

NESTED_ARRAYS = 50_000
"""Depth of the nested-array TOML case (issue 37 item 4's attack)."""


def _cases(folder: Path) -> list[tuple[str, list[str], int]]:
    """(label, millctl arguments, the exit code the case must end with)."""
    fifo = folder / "recipe.fifo"
    os.mkfifo(fifo)
    nested = folder / "nested.toml"
    nested.write_text("x = " + "[" * NESTED_ARRAYS + "]" * NESTED_ARRAYS + "\n", encoding="utf-8")
    socket = str(folder / "nobody.sock")
    client = ["--socket", socket]
    return [
        ("millctl --help", ["--help"], 0),
        ("millctl --version", ["--version"], 0),
        ("millctl status (no service)", ["status", *client], 3),
        ("millctl stop (no service)", ["stop", *client], 3),
        ("millctl estop (no service)", ["estop", *client], 3),
        ("millctl recipe check /dev/zero", ["recipe", "check", "/dev/zero"], 1),
        ("millctl --config /dev/zero status", ["--config", "/dev/zero", "status"], 1),
        ("millctl recipe check FIFO", ["recipe", "check", str(fifo)], 1),
        ("millctl recipe check nested TOML", ["recipe", "check", str(nested)], 1),
        ("millctl config check nested TOML", ["config", "check", str(nested)], 1),
    ]


PROCESSES = [
    ("import: millctl serve (service)", "import millctl.service.server"),
    ("import: firmware_sim, millbus node", "import firmware_sim.__main__"),
    ("import: firmware_sim, CiA 402 drives", "import firmware_sim.__main__, firmware_sim.cia402.process"),
]
"""(label, statement): the module-level imports of each process (the CLI's ``serve`` handler imports the service)."""

TREE_PATH = (
    "import sys\n"
    "sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in type(f).__module__]\n"
    "sys.path.insert(0, {source!r})\n"
)
"""Prefix of a ``python -c`` text that imports millctl and firmware_sim from the tree ``source``."""

FROM_TREE = (
    "import runpy, sys\n"
    "sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in type(f).__module__]\n"
    "sys.path.insert(0, sys.argv[1])\n"
    "sys.argv = ['millctl', *sys.argv[2:]]\n"
    "runpy.run_module('millctl', run_name='__main__', alter_sys=True)\n"
)
"""``python -c`` text that runs ``python -m millctl ARGS`` from the tree in argv[1], not the editable install."""


def _millctl(args: list[str], source: Path | None) -> list[str]:
    if args and args[0] == "-c":  # a PROCESSES statement
        prefix = "" if source is None else TREE_PATH.format(source=str(source))
        return [sys.executable, "-c", prefix + args[1]]
    if source is None:
        return [sys.executable, "-m", "millctl", *args]
    return [sys.executable, "-c", FROM_TREE, str(source), *args]


def _run(command: list[str]) -> tuple[float, float, int]:
    """Wall seconds, CPU seconds (user + system) and exit code of one run of ``command``."""
    env = dict(os.environ)
    env.pop("MILLCTL_CONFIG", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                          check=False, env=env)
    wall_s = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall_s, cpu_s, done.returncode


def measure(
    repeat: int, compare: Path | None = None, processes: bool = False, cli: bool = True
) -> list[dict[str, object]]:
    """One row per case, the baseline first: median wall and CPU seconds, ratios to the baseline, exit codes seen.

    With ``compare``, each case also as ``<case> [compare]``, millctl imported from that source tree;
    with ``processes``, the :data:`PROCESSES` imports too; without ``cli``, not the CLI's cases.
    """
    baseline = [sys.executable, "-c", "pass"]
    with tempfile.TemporaryDirectory(prefix="millctl-startup-") as tmp:
        cases = _cases(Path(tmp)) if cli else []
        if processes:
            cases += [(label, ["-c", statement], 0) for label, statement in PROCESSES]
        if compare is not None:
            cases = [c for case in cases for c in (case, (f"{case[0]} [compare]", *case[1:]))]
        samples: dict[str, list[tuple[float, float, int]]] = {"python -c pass": []}
        for label, _, _ in cases:
            samples[label] = []
        for _ in range(repeat):
            samples["python -c pass"].append(_run(baseline))
            for label, args, _ in cases:
                source = compare if label.endswith(" [compare]") else None
                samples[label].append(_run(_millctl(args, source)))
    expected = {"python -c pass": 0} | {label: code for label, _, code in cases}
    base_wall_s = statistics.median(s[0] for s in samples["python -c pass"])
    base_cpu_s = statistics.median(s[1] for s in samples["python -c pass"])
    rows: list[dict[str, object]] = []
    for label, runs in samples.items():
        wall_s = statistics.median(s[0] for s in runs)
        cpu_s = statistics.median(s[1] for s in runs)
        rows.append({"case": label, "wall_s": wall_s, "cpu_s": cpu_s, "wall_ratio": wall_s / base_wall_s,
                     "cpu_ratio": cpu_s / base_cpu_s if base_cpu_s > 0 else float("nan"),
                     "exit_codes": sorted({s[2] for s in runs}), "expected_exit": expected[label]})
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """Print the table; exit 1 when a case ended with another exit code than it must."""
    parser = argparse.ArgumentParser(prog="python -m bench.startup", description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs of each case, interleaved (median taken)")
    parser.add_argument("--compare", type=Path, metavar="DIR",
                        help="also run each case with millctl from this source tree (PYTHONPATH), e.g. main's")
    parser.add_argument("--processes", action="store_true",
                        help="also time the imports of the service and of the simulated node's two backends")
    parser.add_argument("--only-processes", action="store_true", help="time only those (implies --processes)")
    args = parser.parse_args(argv)
    if args.compare is not None and not (args.compare / "millctl" / "__init__.py").is_file():
        parser.error(f"--compare {args.compare}: no millctl package there (name a source tree's top folder)")
    rows = measure(max(1, args.repeat), args.compare, args.processes or args.only_processes, not args.only_processes)
    load = os.getloadavg()[0]
    sys.stdout.write(f"start-up of millctl, median of {args.repeat} runs each, load average {load:.1f}, "
                     f"{os.cpu_count()} cores\n")
    sys.stdout.write(f"{'case':48} {'wall s':>8} {'× pass':>7} {'CPU s':>8} {'× pass':>7}  exit\n")
    wrong = 0
    for row in rows:
        codes = ",".join(str(c) for c in row["exit_codes"])  # type: ignore[attr-defined]
        mark = "" if row["exit_codes"] == [row["expected_exit"]] else f"  (must be {row['expected_exit']})"
        wrong += bool(mark)
        sys.stdout.write(f"{row['case']:48} {row['wall_s']:8.3f} {row['wall_ratio']:7.1f} "
                         f"{row['cpu_s']:8.3f} {row['cpu_ratio']:7.1f}  {codes}{mark}\n")
    return 1 if wrong else 0


if __name__ == "__main__":
    raise SystemExit(main())
