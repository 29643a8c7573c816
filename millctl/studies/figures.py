"""Figures of a study (matplotlib, needs the plot extra): heat map, Pareto front, sensitivity lines.

Each is one journal column wide with fonts of 7 pt or more (:mod:`millctl.figstyle`), every
axis names its quantity with its unit (:func:`~millctl.studies.metrics.quantity_label`), and
every legend sits beside the data, never over it:

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
from millctl.figstyle import COLUMN_WIDTH_IN, LEGEND_CHARS, RC, TITLE_CHARS, wrap
from millctl.physics.limits import LimitParams, omega_r_max
from millctl.studies.engine import point_config
from millctl.studies.metrics import quantity_label
from millctl.studies.schema import CATEGORICAL, Study
from millctl.units import rad_s_to_rpm, rpm_to_rad_s

PAPER_POINT_RPM = (800.0, 200.0)
"""The paper's recommended operating point (ω_v, ω_r), from its conclusions."""

_LAW_STYLES = {
    LimitLaw.PAPER_EQ9: ("tab:red", "--"),
    LimitLaw.PAPER_EVERY_CYCLE: ("tab:orange", ":"),
    LimitLaw.CORRECTED_EVERY_PHASE: ("tab:blue", "-"),
    LimitLaw.CORRECTED_BEST_PHASE: ("tab:green", "-."),
}


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise InvalidInputError("figures need matplotlib: pip install 'millctl[plot]'") from None
    return plt


def _legend_below(fig: Any, ax: Any, handles: list[Any] | None = None) -> None:
    """The legend just below the panels (constrained layout makes room): it hides no data; entries wrapped."""
    if handles is None:
        handles, labels = ax.get_legend_handles_labels()
    else:
        labels = [h.get_label() for h in handles]
    fig.legend(handles, [wrap(str(label), LEGEND_CHARS) for label in labels], loc="outside lower center", ncols=1,
               frameon=False)


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
    with plt.rc_context(RC):
        fig = _heatmap_figure(plt, study, config, w_r, w_v, grid, best, metric)
    fig.savefig(path, dpi=300, bbox_inches="tight")
    plt.close(fig)
    return path


def _heatmap_figure(
    plt: Any, study: Study, config: MillConfig, w_r: list[float], w_v: list[float], grid: Any,
    best: dict[str, Any], metric: str,
) -> Any:
    fig, ax = plt.subplots(figsize=(COLUMN_WIDTH_IN, 5.0), layout="constrained")
    mesh = ax.pcolormesh(w_v, w_r, grid, shading="nearest", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label=wrap(quantity_label(metric), 45))
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
    ax.plot(*PAPER_POINT_RPM, marker="*", markersize=9, color="white", markeredgecolor="black", linestyle="none",
            label="the paper's recommended point, 200/800 rpm")
    ax.plot(best["vibration_rpm"], best["rotary_rpm"], marker="o", color="red", linestyle="none", label="best point")
    ax.set_xlim(left, right)
    ax.set_ylim(bottom, top)
    ax.set_xlabel("ω_v, cam speed (rpm)")
    ax.set_ylabel("ω_r, vial speed (rpm)")
    ax.set_title(wrap(f"{study.study.name}: {quantity_label(metric)} over the two speeds "
                      f"({config.model.variant} model, {config.mill.cam.shape} cam)", TITLE_CHARS))
    _legend_below(fig, ax)  # below the axes, where it hides no cell of the map
    return fig


def pareto_plot(
    path: Path, rows: Sequence[dict[str, Any]], front: Sequence[dict[str, Any]], metrics: list[str]
) -> Path:
    """Every feasible point in the plane of two metrics, the front drawn over them."""
    plt = _pyplot()
    a, b = (m.lstrip("-") for m in metrics)
    feasible = [r for r in rows if r["feasible"] and math.isfinite(float(r[a])) and math.isfinite(float(r[b]))]
    with plt.rc_context(RC):
        fig, ax = plt.subplots(figsize=(COLUMN_WIDTH_IN, 3.6), layout="constrained")
        ax.scatter([r[a] for r in feasible], [r[b] for r in feasible], s=6, color="0.6", label="feasible points")
        ax.plot([r[a] for r in front], [r[b] for r in front], "o-", color="tab:red", label="Pareto front")
        for set_label, metric in ((ax.set_xlabel, metrics[0]), (ax.set_ylabel, metrics[1])):
            # --pareto maximises NAME and minimises -NAME; the raw value is plotted, never its negative
            better = "lower" if metric.startswith("-") else "higher"
            set_label(wrap(f"{quantity_label(metric)}, {better} is better", TITLE_CHARS))
        ax.set_title(wrap(f"Pareto front of {quantity_label(metrics[0])} and {quantity_label(metrics[1])} "
                          "over the feasible points", TITLE_CHARS))
        _legend_below(fig, ax)
    fig.savefig(path, dpi=300, bbox_inches="tight")
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
    with plt.rc_context(RC):
        fig, axes = plt.subplots(len(lines), 1, figsize=(COLUMN_WIDTH_IN, 1.0 + 2.0 * len(lines)), squeeze=False,
                                 layout="constrained")
        handles: dict[str, Any] = {}
        for ax, (p, cut) in zip(axes[:, 0], lines, strict=True):
            xs = [float(r[p.value]) for r in cut]
            (line,) = ax.plot(xs, [float(r[metric]) for r in cut], "-", color="tab:blue",
                              label="through the best point, one parameter varied")
            ok = [r for r in cut if r["feasible"]]
            bad = [r for r in cut if not r["feasible"]]
            (dots,) = ax.plot([float(r[p.value]) for r in ok], [float(r[metric]) for r in ok], "o", color="tab:blue",
                              label="feasible")
            handles.setdefault(line.get_label(), line)
            handles.setdefault(dots.get_label(), dots)
            if bad:
                (cross,) = ax.plot([float(r[p.value]) for r in bad], [float(r[metric]) for r in bad], "x",
                                   color="tab:red", markersize=6, label="infeasible (a constraint is violated)")
                handles.setdefault(cross.get_label(), cross)
            best_line = ax.axvline(float(best[p.value]), color="tab:red", linewidth=0.8, label="the best point")
            handles.setdefault(best_line.get_label(), best_line)
            ax.set_xlabel(quantity_label(p.value))
            ax.set_ylabel(wrap(quantity_label(metric), 28))
        _legend_below(fig, axes[-1, 0], list(handles.values()))
        fig.suptitle(wrap(f"{study.study.name}: sensitivity of {quantity_label(metric)} to each parameter "
                          "through the best point", TITLE_CHARS))
    fig.savefig(path, dpi=300, bbox_inches="tight")
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


__all__ = ["PAPER_POINT_RPM", "heatmap", "pareto_plot", "sensitivity", "write_figures"]
