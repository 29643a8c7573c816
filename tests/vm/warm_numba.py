"""Compile the node's physics kernels on the host, for the VM: ``python tests/vm/warm_numba.py``.

The simulated node loads its numba kernels at start (``firmware_sim.telemetry.PhysicsCache``),
compiling them once per machine into numba's cache. numba keys that cache by the CPU
LLVM sees: the host's (e.g. ``znver3``) is not the VM's (qemu's software CPU shows as
``k8-sse3``), so without this every node in a fresh VM compiled them again under
emulation: about 20 s of CPU on the host, minutes in the VM, longer than a
scenario's start-up bound (measured: the first scenario of a run timed out waiting
for the node while it compiled).

``tests/vm/run`` sets ``NUMBA_CPU_NAME=generic`` (code for any x86-64, the same key
on the host and in the VM) and ``NUMBA_CACHE_DIR`` (a directory both see) for this
script and for the guest, so the VM's nodes load what the host compiled here. With
the cache current this takes about a second.
"""

from __future__ import annotations

import os
import sys
import time


def main() -> int:
    for name in ("NUMBA_CPU_NAME", "NUMBA_CACHE_DIR"):
        if not os.environ.get(name):
            print(f"warm_numba: {name} is not set: tests/vm/run sets it for the host and the VM alike", file=sys.stderr)
            return 2
    started = time.perf_counter()
    from firmware_sim.telemetry import PhysicsCache
    from millctl.config import load_config
    from millctl.config.loader import packaged_file

    config = load_config(packaged_file("mill.toml")).config
    imported = time.perf_counter()
    PhysicsCache(config).close()  # what the node does at start: load (here: compile) the kernels
    done = time.perf_counter()
    print(
        f"warm_numba: kernels for NUMBA_CPU_NAME={os.environ['NUMBA_CPU_NAME']} ready in "
        f"{os.environ['NUMBA_CACHE_DIR']}: {done - imported:.1f} s (imports {imported - started:.1f} s)",
        file=sys.stderr,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
