"""Issue 40's targets (measured / target / met) and the load guard of ``--write-docs``.

Every figure here is a rate from the CPU time of the measuring thread (``time.thread_time``) or a
ratio of alternated, paired runs, so that other processes' load on a shared machine does not enter
it directly; the host's load is still recorded with every table (``loads``), because a loaded machine
slows even CPU time (caches, frequency, hyper-threads) and makes wall-clock efficiencies meaningless.

``--write-docs`` refuses to replace docs/benchmarks.md with figures from a loaded run: the
1-minute load average may exceed :data:`LOAD_PER_CPU_MAX` per CPU by no more than what the benchmark
itself adds — :data:`OWN_LOAD` at the start of the run (its own process), :data:`OWN_LOAD_PIECES` at
the start of a piece (the average still holds the previous piece's workers and hil processes).
"""

from __future__ import annotations

import os
from typing import Any

LOAD_PER_CPU_MAX = 0.25
"""The load (1-minute average, per CPU) of other work that ``--write-docs`` accepts."""
OWN_LOAD = 1.0
"""What the benchmark adds to the load average as it starts (its own process)."""
OWN_LOAD_PIECES = 5.0
"""What it may add at the start of a piece: two study workers, or the hil tier's nodes, controller and service."""


def load_now() -> dict[str, Any]:
    """The 1/5/15-minute load average and the CPU count, now."""
    one, five, fifteen = os.getloadavg()
    return {"loadavg": [round(one, 2), round(five, 2), round(fifteen, 2)], "cpus": os.cpu_count() or 1}


def load_threshold(cpus: int, own: float = OWN_LOAD) -> float:
    """The largest 1-minute load average a run may see and still write the document."""
    return LOAD_PER_CPU_MAX * cpus + own


def loaded(res: dict[str, Any]) -> str | None:
    """Why ``res`` came from a loaded run (the load, where, the threshold), or None if it did not."""
    cpus = int(res["machine"]["cpu_count"] or 1)
    seen = [("the start", float(res["machine"]["loadavg"][0]), OWN_LOAD)]
    seen += [(f"the start of {p}", float(v["loadavg"][0]), OWN_LOAD_PIECES) for p, v in res.get("loads", {}).items()]
    for where, load, own in seen:
        threshold = load_threshold(cpus, own)
        if load > threshold:
            return (
                f"the 1-minute load average was {load:.2f} at {where} of this run on {cpus} CPUs, above the "
                f"threshold {threshold:.2f} ({LOAD_PER_CPU_MAX} per CPU of other work + {own:g} for the benchmark "
                "itself): figures from a loaded host are not committed (docs/benchmarks.md); rerun on a quiet host"
            )
    return None


def _row(name: str, measured: float | None, target: float, unit: str, at_most: bool = False) -> dict[str, Any]:
    met = None if measured is None else (measured <= target if at_most else measured >= target)
    return {"name": name, "measured": measured, "target": target, "unit": unit, "at_most": at_most, "met": met}


def issue40(res: dict[str, Any]) -> list[dict[str, Any]]:
    """Part 3's targets from the pieces that ran (a target whose piece did not run is left out)."""
    rows = []
    compiled = res.get("compiled", {})
    if "batch" in compiled:
        b = compiled["batch"]
        rows.append(_row("batch kernel, one rod's event", b["one"]["events_per_cpu_s"], 5e5, "events/s/core"))
        rows.append(_row("batch kernel, a whole six-rod scene", b["all"]["events_per_cpu_s"], 2e5, "scenes/s/core"))
    api = compiled.get("public_api", {})
    if "one_rod" in api:
        label = "one event through the public API, one rod's event (`EventCall`)"
        rows.append(_row(label, api["one_rod"]["us_per_event"], 3.0, "µs", True))
    if "us_per_event" in api:
        label = "one event through the public API, a whole six-rod scene (`first_impact`)"
        rows.append(_row(label, api["us_per_event"], 3.0, "µs", True))
    st = res.get("study", {})
    if "arrays" in st:
        side = round(st["arrays"]["points"] ** 0.5)
        label = f"{side}×{side} level-(b) map, {st['arrays'].get('cam_phases', 4)} cam phases"
        rows.append(_row(label, st["arrays"]["points_per_cpu_s"], 1e5, "points/s/core"))
    if "arrays_integrated" in st:
        side = round(st["arrays_integrated"]["points"] ** 0.5)
        label = f"{side}×{side} level-(b) map, integrated over the cam phase to 1 %"
        rows.append(_row(label, st["arrays_integrated"]["points_per_cpu_s"], 1e5, "points/s/core"))
    for key, label in (("local", "2 local cores"), ("dask", "2-worker local Dask cluster")):
        if key in st.get("parallel", {}):
            rows.append(_row(f"parallel efficiency, {label}", st["parallel"][key]["efficiency"], 0.8, "share"))
    if "offline" in st:
        rows.append(_row("level (c) simulation", st["offline"]["events_per_cpu_s"], 1e5, "events/s/core"))
    if "offline_slip" in st:
        rows.append(_row("level (c) with slip", st["offline_slip"]["events_per_cpu_s"], 1e5, "events/s/core"))
    if "agreement_c" in st:
        rows.append(_row("level (c) agrees event for event", st["agreement_c"]["fraction"], 0.999, "share of scenes"))
    if "agreement_c_slip" in st:
        share = st["agreement_c_slip"]["fraction"]
        rows.append(_row("level (c) with slip agrees event for event", share, 0.999, "share of scenes"))
    return rows


def report(res: dict[str, Any]) -> list[str]:
    """The targets table (printed with every run) and the load of the pieces it came from."""
    rows = issue40(res)
    if not rows:
        return []
    out = [
        "## Issue 40 targets",
        "",
        "| target | measured | target | met |",
        "|---|---|---|---|",
    ]
    for r in rows:
        bound = "≤" if r["at_most"] else "≥"
        measured = "—" if r["measured"] is None else f"{r['measured']:.3g}"
        met = "—" if r["met"] is None else ("yes" if r["met"] else "**no**")
        out.append(f"| {r['name']} ({r['unit']}) | {measured} | {bound} {r['target']:.3g} | {met} |")
    api = res.get("compiled", {}).get("public_api", {})
    one = api.get("one_rod", {})
    if "wrapping_us" in one:
        out += [
            "",
            f"One rod's event through the public API (a prepared `methods.EventCall(model)`, the scene as four "
            f"floats): {one['us_per_event']:.3g} µs = the kernel's {one['kernel_us_per_event']:.3g} µs for the same "
            f"scenes in the batch + {one['wrapping_us']:.3g} µs of Python call path.",
        ]
    if "wrapping_us" in api:
        out += [
            "",
            f'One event through the public API (`methods.first_impact(scene, "exact")`, a whole six-rod scene): '
            f"{api['us_per_event']:.3g} µs = the kernel's {api['kernel_us_per_scene']:.3g} µs for the same scenes "
            f"in the batch + {api['wrapping_us']:.3g} µs of Python call path.",
        ]
    out += ["", load_line(res, *res.get("loads", {})), ""]
    return out


def load_line(res: dict[str, Any], *pieces: str) -> str:
    """One line: the host's load at the start of each named piece and the CPU count (for every table)."""
    loads = res.get("loads", {})
    parts = [f"{p} {loads[p]['loadavg'][0]:.2f}" for p in pieces if p in loads]
    cpus = res["machine"]["cpu_count"]
    shown = "; ".join(parts) if parts else f"run start {res['machine']['loadavg'][0]:.2f}"
    return f"Host load (1-minute average at the start of each piece) on {cpus} CPUs: {shown}."


__all__ = [
    "LOAD_PER_CPU_MAX",
    "OWN_LOAD",
    "OWN_LOAD_PIECES",
    "issue40",
    "load_line",
    "load_now",
    "load_threshold",
    "loaded",
    "report",
]
