"""Figures of a study (matplotlib, needs the plot extra): heat map, Pareto front, sensitivity lines.

* heat map of a metric over (ω_v, ω_r) — the axes of the paper's Fig. 5 — with
  every law's limit curve, the forbidden region of the study's envelope law
  hatched, and the paper's recommended 200/800 rpm point marked; when other
  parameters vary too, the slice through the best point is drawn;
* Pareto front of two metrics over every feasible point;
* one-parameter sensitivity lines of the objective through the best point.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from millctl.config.models import LimitLaw, MillConfig
from millctl.errors import InvalidInputError
from millctl.physics.limits import LimitParams, omega_r_max
from millctl.studies.engine import point_config
from millctl.studies.schema import CATEGORICAL, Parameter, Study
from millctl.units import rad_s_to_rpm, rpm_to_rad_s

PAPER_POINT_RPM = (800.0, 200.0)
"""The paper's recommended operating point (ω_v, ω_r), from its conclusions."""

_LAW_STYLES = {
    LimitLaw.PAPER_EQ9: ("tab:red", "--"),
    LimitLaw.PAPER_EVERY_CYCLE: ("tab:orange", ":"),
    LimitLaw.CORRECTED_EVERY_PHASE: ("tab:blue", "-"),
    LimitLaw.CORRECTED_BEST_PHASE: ("tab:green", "-."),
}


_UNITS = (
    ("_j_g_s", "J g⁻¹ s⁻¹"), ("_kj_g", "kJ/g"), ("_j_g", "J/g"), ("_m_s2", "m/s²"), ("_n_per_m", "N/m"),
    ("_rpm_s", "rpm/s"), ("_rpm", "rpm"), ("_hz", "Hz"), ("_kw", "kW"), ("_w", "W"), ("_mj", "mJ"), ("_j", "J"),
    ("_kpa", "kPa"), ("_mpa", "MPa"), ("_gpa", "GPa"), ("_kn", "kN"), ("_n", "N"), ("_mm", "mm"), ("_m", "m"),
    ("_deg", "°"), ("_h", "h"), ("_s", "s"), ("_c", "°C"), ("_kg", "kg"), ("_g", "g"),
)
"""A metric identifier's unit suffix and the unit it names (longest first: ``_j_g_s`` before ``_s``)."""
_NAMES = {"rotary_rpm": "ω_r, vial speed (rpm)", "vibration_rpm": "ω_v, cam speed (rpm)"}
_WORDS = {"p10": "10th percentile", "p90": "90th percentile", "sim": "simulated", "rpm": "rpm"}


def metric_label(name: str) -> str:
    """A metric identifier as an axis label: ``impact_energy_p90_j`` → ``impact energy, 90th percentile (J)``.

    A leading ``-`` (a metric maximised in ``--pareto``) is not part of the quantity plotted.
    """
    name = name.lstrip("-")
    if name in _NAMES:
        return _NAMES[name]
    unit = ""
    for suffix, text in _UNITS:
        if name.endswith(suffix) and len(name) > len(suffix):
            name, unit = name[: -len(suffix)], text
            break
    words = name.split("_")
    qualifiers = [_WORDS[w] for w in words if w in ("p10", "p90")]
    words = [_WORDS.get(w, w) for w in words if w not in ("p10", "p90")]
    text = " ".join(words) + (", " + ", ".join(qualifiers) if qualifiers else "")
    return f"{text} ({unit})" if unit else text


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise InvalidInputError("figures need matplotlib: pip install 'millctl[plot]'") from None
    return plt


def _slice(rows: Sequence[dict[str, Any]], best: dict[str, Any], free: set[str], study: Study) -> list[dict[str, Any]]:
    """Rows that agree with the best point on every parameter outside ``free``."""
    fixed = [p.value for p in study.parameters if p.value not in free]
    return [r for r in rows if all(r[k] == best[k] for k in fixed)]


def _edges(values: list[float]) -> tuple[float, float]:
    """The outer edges of cells centred on sorted values (half a step beyond each end)."""
    if len(values) < 2:
        return values[0] - 0.5, values[0] + 0.5
    return values[0] - 0.5 * (values[1] - values[0]), values[-1] + 0.5 * (values[-1] - values[-2])


def heatmap(
    path: Path, study: Study, runner_task: Any, rows: Sequence[dict[str, Any]], best: dict[str, Any], metric: str
) -> Path | None:
    """Heat map of ``metric`` over (ω_v, ω_r) with the limit curves; None unless both speeds vary."""
    names = {p.value for p in study.parameters}
    if not {"rotary_rpm", "vibration_rpm"} <= names:
        return None
    plt = _pyplot()
    cut = _slice(rows, best, {"rotary_rpm", "vibration_rpm"}, study)
    w_r = sorted({float(r["rotary_rpm"]) for r in cut})
    w_v = sorted({float(r["vibration_rpm"]) for r in cut})
    grid = np.full((len(w_r), len(w_v)), np.nan)
    for r in cut:
        grid[w_r.index(float(r["rotary_rpm"])), w_v.index(float(r["vibration_rpm"]))] = float(r[metric])
    config: MillConfig = point_config(runner_task({p.value: best[p.value] for p in study.parameters}))
    fig, ax = plt.subplots(figsize=(8, 6))
    mesh = ax.pcolormesh(w_v, w_r, grid, shading="nearest", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label=metric_label(metric))
    params = LimitParams.from_config(config)
    left, right = _edges(w_v)
    bottom, top = _edges(w_r)
    curve_v = np.linspace(left, right, 400)
    for law, (colour, style) in _LAW_STYLES.items():
        limit = rad_s_to_rpm(omega_r_max(law, params, rpm_to_rad_s(curve_v)))
        ax.plot(curve_v, limit, color=colour, linestyle=style, label=f"{law.value} limit")
    law_name = study.constraints.law
    if law_name != "none":
        allowed = (1.0 - config.interlock.margin) * rad_s_to_rpm(
            omega_r_max(LimitLaw(law_name), params, rpm_to_rad_s(curve_v))
        )
        ax.fill_between(
            curve_v,
            np.minimum(allowed, top),
            top,
            facecolor=(1.0, 1.0, 1.0, 0.3),
            hatch="//",
            edgecolor="0.2",
            linewidth=0.0,
            label=f"forbidden under {law_name} (margin {config.interlock.margin:.0%})",
        )
    ax.plot(*PAPER_POINT_RPM, marker="*", markersize=16, color="white", markeredgecolor="black", linestyle="none")
    ax.annotate("paper: 200/800", PAPER_POINT_RPM, textcoords="offset points", xytext=(8, 8), color="white")
    ax.plot(best["vibration_rpm"], best["rotary_rpm"], marker="o", color="red", linestyle="none", label="best point")
    ax.set_xlim(left, right)
    ax.set_ylim(bottom, top)
    ax.set_xlabel("ω_v, cam speed (rpm)")
    ax.set_ylabel("ω_r, vial speed (rpm)")
    ax.set_title(f"{study.study.name}: {metric_label(metric)}\n({config.model.variant} model, "
                 f"{config.mill.cam.shape} cam)")
    # below the axes, where it hides no cell of the map
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def pareto_plot(
    path: Path, rows: Sequence[dict[str, Any]], front: Sequence[dict[str, Any]], metrics: list[str]
) -> Path:
    """Every feasible point in the plane of two metrics, the front drawn over them."""
    plt = _pyplot()
    a, b = (m.lstrip("-") for m in metrics)
    feasible = [r for r in rows if r["feasible"] and math.isfinite(float(r[a])) and math.isfinite(float(r[b]))]
    fig, ax = plt.subplots(figsize=(7, 5))
    ax.scatter([r[a] for r in feasible], [r[b] for r in feasible], s=10, color="0.6", label="feasible points")
    ax.plot([r[a] for r in front], [r[b] for r in front], "o-", color="tab:red", label="Pareto front")
    for set_label, metric in ((ax.set_xlabel, metrics[0]), (ax.set_ylabel, metrics[1])):
        better = "higher" if metric.startswith("-") else "lower"
        set_label(f"{metric_label(metric)}, {better} is better")  # the raw value is plotted, never its negative
    ax.set_title(f"Pareto front: {metric_label(metrics[0])} against {metric_label(metrics[1])}", fontsize=10)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def sensitivity(
    path: Path, study: Study, rows: Sequence[dict[str, Any]], best: dict[str, Any], metric: str
) -> Path | None:
    """The metric along each numeric parameter through the best point; None when no parameter has two values."""
    lines = []
    for p in study.parameters:
        if p in CATEGORICAL:
            continue
        cut = sorted(_slice(rows, best, {p.value}, study), key=lambda r: float(r[p.value]))
        if len(cut) > 1:
            lines.append((p, cut))
    if not lines:
        return None
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(lines), figsize=(4 * len(lines), 3.5), squeeze=False)
    for ax, (p, cut) in zip(axes[0], lines, strict=True):
        ax.plot([float(r[p.value]) for r in cut], [float(r[metric]) for r in cut], "-", color="tab:blue",
                label="through the best point")
        ok = [r for r in cut if r["feasible"]]
        bad = [r for r in cut if not r["feasible"]]
        ax.plot([float(r[p.value]) for r in ok], [float(r[metric]) for r in ok], "o", color="tab:blue",
                label="feasible")
        if bad:
            ax.plot([float(r[p.value]) for r in bad], [float(r[metric]) for r in bad], "x", color="tab:red",
                    markersize=8, label="infeasible (a constraint is violated)")
        ax.axvline(float(best[p.value]), color="tab:red", linewidth=0.8)
        ax.set_xlabel(metric_label(Parameter(p).value))
        ax.set_ylabel(metric_label(metric))
        ax.legend(fontsize=7)
    fig.suptitle(f"{study.study.name}: sensitivity of {metric_label(metric)} through the best point")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_figures(
    directory: Path,
    study: Study,
    runner: Any,
    result: Any,
    metric: str | None,
    pareto: list[str] | None,
    front: Sequence[dict[str, Any]] | None,
) -> list[str]:
    """Every figure the study supports, as PNGs in ``directory``; returns their paths."""
    directory.mkdir(parents=True, exist_ok=True)
    written: list[Path | None] = []
    chosen = metric or next(iter(result.objective))
    if chosen not in result.metrics:
        raise InvalidInputError(f"--heatmap {chosen}: not a metric of the study ({', '.join(result.metrics)})")
    if result.best is not None:
        written.append(heatmap(directory / "heatmap.png", study, runner.task, result.rows, result.best, chosen))
        written.append(sensitivity(directory / "sensitivity.png", study, result.rows, result.best, chosen))
    if pareto is not None and front is not None:
        written.append(pareto_plot(directory / "pareto.png", result.rows, front, pareto))
    return [str(p) for p in written if p is not None]


__all__ = ["PAPER_POINT_RPM", "heatmap", "metric_label", "pareto_plot", "sensitivity", "write_figures"]
