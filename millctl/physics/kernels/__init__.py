"""Compiled kernels (numba) of the exact engine: one first impact at a time, or many scenes at once.

The same algorithm as the readable numpy/scipy reference (:mod:`..detachment`,
:mod:`..events`, :mod:`..simulate`), written as scalar loops and compiled once per
machine (``cache=True``), one module a concept:

* :mod:`.layout` — the named array layouts: scene rows (:data:`PARAMS`), result rows
  (:data:`OUT`, :data:`TELEMETRY`), rod states, trig-sum rows, function codes;
* :mod:`.trig` — N(t)/m as a constant plus three cosines, eqs 4–7
  (:func:`~millctl.physics.kinematics.normal_force_per_mass`);
* :mod:`.motion` — rods in the vial frame, held (eq. 11) or flying (eq. 10, in the flight's own
  time τ and its departure's cam phase), the wall gap with its triple root divided out
  (:func:`~millctl.physics.flight.departure_wall_gap`), the rod–rod separation (eq. 13, 2 r_r);
* :mod:`.roots` — Brent's bracketed root finder, a line-by-line port of scipy's ``brentq``
  (same tolerances as the reference), so both engines stop on the same test, and Newton's method kept in
  its bracket where the slope comes with the value (N's falling zeros, a rod pair's separation);
* :mod:`.detach` — the certified first falling zero of N (Taylor bound, critical points,
  bisection), searched one revolution at a time (one cam period with the vial at rest) and only
  when the event loop reaches the end of what has been searched (lazy);
* :mod:`.contacts` — the bracketing scan of every pair (separation, exact derivative, the
  second-order margin that lets a grazing minimum be skipped only when it provably stays apart);
* :mod:`.events` — the event loop to the first impact and its energy (eq. 19), the batch entry point;
* :mod:`.telemetry` — level (b): the node telemetry's cam-phase samples with the no-slip check;
* :mod:`.phase_rule` — level (b) integrated over the cam phase: the studies' adaptive trapezoid rule;
* :mod:`.scene_call` — one scene at a time with reused arrays (the public API's ``exact``), and
  :class:`EventCall`: one model's events, the scene as four floats, on arrays made and checked once.

No array is allocated per scene: a batch makes its work arrays once (:func:`.events._scratch`), as views
of one buffer (:func:`.events._scratch_in`) that the single-scene path keeps between calls.

**Error model.** Every kernel is compiled with ``error_model="numpy"``: a float division by zero gives
inf or nan, as in numpy, instead of raising. No kernel divides by zero on a valid scene (the guards are
explicit), and with numba's default ("python") every division carries a check and an exception path
that keeps LLVM from inlining the small kernels and from pruning their reference counts (the batch of
:func:`first_impacts` runs 5–11 % faster, the same numbers bit for bit). Every kernel that makes no array
(all but the batch loops, :func:`.events._scratch`, :func:`.events._scratch_in`, :func:`.trig._trig_rows` and
:func:`.detach._detachment_times`) is a *leaf kernel* (:func:`.layout.leaf_kernel`), compiled without
numba's reference counting (``_nrt=False``): a call with array arguments, or a view of one, otherwise
increments and decrements the array's count atomically, which took 12 % of a one-rod event's time in a perf
profile while only the trig sums, motion and root finder were so compiled. A leaf kernel cannot call one
that allocates (numba compiles the callee with the caller's flags), hence the stackless bisection of
:func:`.detach._split_cell`.

Event loop: every rod starts pinned at eq. 11's angle; rods detach at their own
times (``rods="all"``, :func:`first_impacts`) or only rod 0 does, the others
held on the wall (``rods="one"``, the node telemetry's sample and a design study's
unit). The loop stops at the first impact: nothing is re-scheduled after it.

**Zero-length flight** (decided here, the same in every engine): a departure whose
wall gap, with the departure root divided out, is ≤ 0 at the departure instant
(its leading coefficient: the free path does not leave the wall — the paper's
detachment where the true N is still positive, or N touching zero with zero slope)
is not a flight and books no impact: the rod stays held through the current dip of
N and may detach again when N has risen above zero and falls again. Any other
flight, however short, is a flight, and its landing is an impact (of negligible
energy when the flight is tiny).

Cam: the single-acting circular cam of eqs 1–3 (lift r_d sin α). Scenes are given
as rows of parameters (:data:`PARAMS`, :func:`scene_row`).

**Numba's cache across modules.** numba invalidates a cached function only when the file that
defines it changes, not when a function it calls from another file does ("Caching limitations" in
numba's notes on caching). :func:`_drop_stale_cache` closes that gap on import: it hashes every
source of this package and of :mod:`..legacy_kernel` (which calls these kernels) and, when the hash
differs from the one stamped in this package's ``__pycache__``, deletes those modules' numba cache
files (``*.nbi``, ``*.nbc``) before anything is loaded from them. With ``NUMBA_CACHE_DIR`` set the
cache lives elsewhere and is not touched: clear it yourself after editing a kernel.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent
_STAMP = "kernel-sources.sha256"


def _drop_stale_cache(package: Path = _PACKAGE) -> None:
    """Delete the numba cache of the kernels when any of their sources changed since it was made."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    sources = [*sorted(package.glob("*.py")), package.parent / "legacy_kernel.py"]
    digest = hashlib.sha256()
    for path in sources:
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    stamp_dir = package / "__pycache__"
    stamp = stamp_dir / _STAMP
    want = digest.hexdigest()
    try:
        if stamp.read_text(encoding="ascii").strip() == want:
            return
    except OSError:
        pass
    try:
        legacy = (package.parent / "__pycache__").glob("legacy_kernel.*.nb[ic]")
        stale = [*stamp_dir.glob("*.nb[ic]"), *legacy]
        for path in stale:
            path.unlink(missing_ok=True)
        stamp_dir.mkdir(exist_ok=True)
        partial = stamp.with_name(f"{_STAMP}.{os.getpid()}")
        partial.write_text(want + "\n", encoding="ascii")
        partial.replace(stamp)
    except OSError:  # a read-only install: numba then keeps its cache in memory only
        return


_drop_stale_cache()

# ruff: noqa: E402 — the cache is checked before any kernel module is imported
# the private names below are those legacy_kernel.py and the kernel tests read as kernels._X: re-exported
from millctl.physics.kernels.detach import _falling_zero_windowed as _falling_zero_windowed
from millctl.physics.kernels.detach import _never_detaches as _never_detaches
from millctl.physics.kernels.detach import detachment_times
from millctl.physics.kernels.events import _depart as _depart
from millctl.physics.kernels.events import first_impacts
from millctl.physics.kernels.layout import _A0 as _A0
from millctl.physics.kernels.layout import _L as _L
from millctl.physics.kernels.layout import _N as _N
from millctl.physics.kernels.layout import _R0 as _R0
from millctl.physics.kernels.layout import _RD as _RD
from millctl.physics.kernels.layout import _RR as _RR
from millctl.physics.kernels.layout import _S_TH as _S_TH
from millctl.physics.kernels.layout import _STATE_COLUMNS as _STATE_COLUMNS
from millctl.physics.kernels.layout import _TH0 as _TH0
from millctl.physics.kernels.layout import _WR as _WR
from millctl.physics.kernels.layout import _WV as _WV
from millctl.physics.kernels.layout import OUT, PARAMS, TELEMETRY, WALL, FloatArray, scene_row, scene_rows
from millctl.physics.kernels.motion import _rel as _rel
from millctl.physics.kernels.phase_rule import phase_integral
from millctl.physics.kernels.scene_call import EventCall, SceneCall
from millctl.physics.kernels.telemetry import telemetry_at, telemetry_batch, telemetry_samples
from millctl.physics.kernels.trig import _trig as _trig
from millctl.physics.kernels.trig import _trig_rows as _trig_rows

__all__ = [
    "OUT",
    "PARAMS",
    "TELEMETRY",
    "WALL",
    "EventCall",
    "FloatArray",
    "SceneCall",
    "detachment_times",
    "first_impacts",
    "phase_integral",
    "scene_row",
    "scene_rows",
    "telemetry_at",
    "telemetry_batch",
    "telemetry_samples",
]
