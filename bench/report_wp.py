"""The work-precision sections of docs/benchmarks.md: the headline ratios, the tables, failures and worst energies.

Split from :mod:`bench.report` (one concern a module); every figure comes from the results JSON.
"""

from __future__ import annotations

from typing import Any

from bench.report_format import g, ms

PLOT_REL = "img/work-precision.png"
"""The plot's path relative to docs/."""
HARD_COLUMNS = (
    ("exact", "tol=4ulp"),
    ("exact", "tol=1e-09"),
    ("legacy", "dt=0.0001"),
    ("legacy", "dt=1e-06"),
    ("legacy", "dt=1e-08"),
    ("legacy-arcs", "q=360 dt=1e-05"),
    ("ivp", "rtol=1e-10"),
)


def headline(wp: dict[str, Any], command: str) -> list[str]:
    """The headline ratios, on the time error first, then on the other two error measures."""
    h = wp["headline"]["time_s"]
    out = ["## Headline ratios", "", f"Reproduce with `{command}`; on the median collision-time error:", ""]
    names = {
        "legacy": "the paper's fixed-step scheme",
        "legacy-arcs": "its q-arc wall",
        "legacy-interp": "its interpolated variant",
        "legacy-compiled": "the paper's scheme compiled the same way (numba, like for like)",
    }
    for key, name in names.items():
        if key in h:
            best = h[key]["at_most_accurate"]
            out.append(
                f"- **Exact engine vs {name}** (`{key}`): at the baseline's most accurate setting ({best['setting']}, "
                f"median error {g(best['error'])} s) the baseline takes **{g(best['speedup'])}×** the exact engine's "
                f"time per event at that error or better; over the baseline's whole sweep {g(h[key]['speedup_min'])}× "
                f"to {g(h[key]['speedup_max'])}× (below 1: the baseline is the faster one at its own error)."
            )
    if "ivp" in h:
        iv = h["ivp"]
        levels = ", ".join(f"{g(p['error'])} s: {g(p['speedup'])}×" for p in iv["per_error"])
        out.append(
            f"- **Exact engine vs solve_ivp at equal error**: solve_ivp takes **{g(iv['speedup_median'])}×** the "
            f"exact engine's time per event (median over common error levels; range {g(iv['speedup_min'])}× to "
            f"{g(iv['speedup_max'])}×; at {levels})."
        )
    else:
        out.append("- Exact engine vs solve_ivp: no common error level on the measured curves.")
    for key, what in (("point_m", "contact-point error"), ("energy_rel", "relative energy error")):
        other = wp["headline"].get(key, {})
        parts = [f"`{b}` {g(other[b]['at_most_accurate']['speedup'])}×" for b in names if b in other]
        if "ivp" in other:
            parts.append(f"solve_ivp at equal error {g(other['ivp']['speedup_median'])}× (median)")
        if parts:
            out.append(f"- The same ratios on the median {what}: " + ", ".join(parts) + ".")
    exact = [x for x in wp["summary"] if x["method"] == "exact"]
    if exact:
        cheapest = min(exact, key=lambda x: x["seconds_per_event"])
        costs = [x["seconds_per_event"] for x in exact]
        out.append(
            "- The exact engine's time per event "
            + (
                "hardly depends on its tolerance (bracketing dominates, not brentq)"
                if max(costs) < 1.5 * min(costs)
                else "depends on its tolerance"
            )
            + f": {ms(min(costs))}–{ms(max(costs))} ms over its sweep; its cheapest setting in this run was "
            f"{cheapest['setting']}"
            + (
                ", which is also its most accurate, so every ratio above is taken against that one point."
                if cheapest["setting"] == "tol=4ulp"
                else "."
            )
        )
    out += [
        "",
        "How: each method's (time per event, median error) points are reduced to their Pareto front; the "
        "exact engine's time at a baseline's error is interpolated log–log between its measured points "
        "(a baseline error looser than the exact engine's loosest point is charged that cheapest point: "
        '"at equal or worse error"). Against solve_ivp the ratio is taken at each error solve_ivp reaches '
        "that the exact engine also reaches.",
        "",
    ]
    return out


def tables(wp: dict[str, Any]) -> list[str]:
    """The work-precision tables: every method and setting, the hard cases, the failures."""
    scenes = wp["scenes"]
    hard = [s for s in scenes if s["hard"]]
    kinds: dict[str, int] = {}
    for r in wp["references"].values():
        kinds[r["kind"]] = kinds.get(r["kind"], 0) + 1
    out = [
        "## 1. Work–precision",
        "",
        f"![work-precision]({PLOT_REL})",
        "",
        f"Scenes: {len(scenes) - len(hard)} from a scrambled Latin hypercube (scipy.stats.qmc, seeded; "
        "ω_r 20–220 rpm, ω_v 0–1200 rpm, θ0, α0, r_d 0–2 mm, every 4th with r_d = 0; Set A, corrected variant) "
        f"and {len(hard)} hard cases. References: "
        + ", ".join(f"{v} {k}" for k, v in sorted(kinds.items()))
        + f" (closed form evaluated in mpmath; largest closed-form vs mpmath disagreement "
        f"{g(wp['closed_vs_mpmath_max_s'])} s). Time per event: one `first_impact` call (detachment search "
        "included, identical for all methods), median of repeats, median over scenes. Errors: median (and max) "
        "over matched events; contact point in m, energy relative. "
        "An event is *matched* when it names the reference's pair within max(½ flight, 2 × slack); *spurious* "
        "when it comes earlier than the reference or where there is none; *missed* when it comes later or never.",
        "",
        "| method | setting | scenes | ms/event | median \\|Δt\\| s | max \\|Δt\\| s | median \\|Δp\\| m "
        "| median \\|ΔE\\|/E | max \\|ΔE\\|/E | median \\|Δv_n\\|/v_n | matched | missed | spurious |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in wp["summary"]:
        note = " (one-rod hard cases)" if s["one_rod_only"] else ""
        out.append(
            f"| {s['method']} | {s['setting']}{note} | {s['scenes']} | {ms(s['seconds_per_event'])} "
            f"| {g(s['time_s_median'])} | {g(s['time_s_max'])} | {g(s['point_m_median'])} "
            f"| {g(s['energy_rel_median'])} | {g(s['energy_rel_max'])} | {g(s['v_n_rel_median'])} "
            f"| {s['matched']} | {s['missed']} "
            f"| {s['spurious']} |"
        )
    out += ["", *_worst_energy_lines(wp)]
    totals: dict[str, list[int]] = {}
    for s in wp["summary"]:
        t = totals.setdefault(s["method"], [0, 0, 0])
        t[0] += s["scenes"]
        t[1] += s["missed"]
        t[2] += s["spurious"]
    out += ["", "Missed and spurious events per method (all settings, all scenes):", ""]
    out += ["| method | runs | missed | spurious |", "|---|---|---|---|"]
    out += [f"| {m} | {t[0]} | {t[1]} | {t[2]} |" for m, t in totals.items()]
    out += [
        "",
        "Where they happened (scene: verdict × number of settings; *at t = 0* marks an event at the start):",
        "",
    ]
    out += _failures(wp["rows"])
    out += [
        "",
        "### Hard cases",
        "",
        "|Δt| (s) of the first impact, or what went wrong (dt = 1e-8 runs only on the one-rod cases: its cost "
        "grows like 1/dt):",
        "",
    ]
    cols = [c for c in HARD_COLUMNS if any(r["method"] == c[0] and r["setting"] == c[1] for r in wp["rows"])]
    out.append("| case | note | reference | " + " | ".join(f"{m} {s}" for m, s in cols) + " |")
    out.append("|---|---|---|" + "---|" * len(cols))
    for sc in hard:
        cells = []
        for m, s in cols:
            row = next(
                (r for r in wp["rows"] if r["scene"] == sc["name"] and r["method"] == m and r["setting"] == s), None
            )
            if row is None:
                cells.append("not run")
            elif row["verdict"] == "matched":
                cells.append(g(row["time_s"], 2))
            else:
                cells.append(f"**{row['verdict']}**")
        out.append(
            f"| {sc['name']} | {sc['note']} | {wp['references'][sc['name']]['kind']} | " + " | ".join(cells) + " |"
        )
    out.append("")
    return out


def _failures(rows: list[dict[str, Any]]) -> list[str]:
    """One line per method: the scenes where it missed or faked the first impact."""
    by_method: dict[str, dict[tuple[str, str], int]] = {}
    for r in rows:
        if r["verdict"] in ("missed", "spurious"):
            tag = r["verdict"] + (" at t = 0" if r["event_time_s"] == 0.0 else "")
            counts = by_method.setdefault(r["method"], {})
            counts[(r["scene"], tag)] = counts.get((r["scene"], tag), 0) + 1
    if not by_method:
        return ["- none"]
    return [
        f"- `{method}`: " + ", ".join(f"{scene} {tag} ×{n}" for (scene, tag), n in counts.items())
        for method, counts in by_method.items()
    ]


def _worst_energy_lines(wp: dict[str, Any]) -> list[str]:
    """Where each method's largest relative energy error came from: the scene and its reference impact."""
    refs = wp["references"]
    worst: dict[str, dict[str, Any]] = {}
    for row in wp["rows"]:
        err = row.get("energy_rel")
        if err is not None and err > worst.get(row["method"], {}).get("energy_rel", -1.0):
            worst[row["method"]] = row
    lines = [
        "The largest |ΔE|/E of each method, and the reference impact it came from (a nearly grazing impact, "
        "with a tiny normal velocity, turns a small error in where the contact is found into a large relative "
        "error in energy; the medians carry the comparison):",
        "",
    ]
    for method, row in sorted(worst.items()):
        ref = refs[row["scene"]]["event"]
        lines.append(
            f"- `{method}` {row['setting']}: |ΔE|/E = {row['energy_rel']:.3g} on {row['scene']} "
            f"(reference v_n = {abs(ref['normal_velocity_m_s']):.3g} m/s, E = {ref['energy_j']:.3g} J)"
        )
    return lines


__all__ = ["HARD_COLUMNS", "PLOT_REL", "headline", "tables"]
