"""``millctl limits --plot``: which rotary speed is safe, at a glance, and the admissible cam phases.

Upper panel (the counterpart of the paper's Fig. 5): the region the interlock
allows (the configured law with its margin, capped at the rotary drive's
maximum), every other limit law as a line, the vibration speeds where the
configured law is not the every-cycle bound (hatched; the number comes from
:func:`millctl.safety.regime.regime_warning`, as in the table and the TUI),
and the operating points: measured and target from a running service
(``--live``), the steps of a recipe (``--recipe``), points given by hand
(``--at``). A planned point outside the envelope is drawn as a red cross.

Lower panel (Fig. 6): the cam phases sin α for which eq. 7 has a real
detachment angle, shaded; the printed eq. 8b is drawn as the erratum it is.

The figure is one journal column wide with fonts of 7 pt or more (:mod:`millctl.figstyle`),
each panel's legend right under its x label, where it hides nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from millctl.config.models import LimitLaw
from millctl.figstyle import COLUMN_WIDTH_IN, LEGEND_CHARS, RC, TITLE_CHARS, wrap
from millctl.physics.cam import lift_speed_array
from millctl.physics.limits import LAWS, omega_r_max, sin_alpha_bound_consistent, sin_alpha_bound_printed_eq8b
from millctl.safety import Envelope, SpeedPoint
from millctl.safety.envelope import LAW_IN_WORDS
from millctl.safety.regime import regime_warning
from millctl.units import rad_s_to_rpm, rpm_to_rad_s

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from millctl.config.models import MillConfig

LAW_STYLE = {
    LimitLaw.PAPER_EQ9: ("tab:blue", "--"),
    LimitLaw.PAPER_EVERY_CYCLE: ("tab:purple", "-."),
    LimitLaw.CORRECTED_EVERY_PHASE: ("tab:orange", ":"),
    LimitLaw.CORRECTED_BEST_PHASE: ("tab:brown", (0, (5, 1, 1, 1, 1, 1))),
}


@dataclass(frozen=True)
class OperatingPoints:
    """What to mark on the envelope: the mill now, its target, and planned points."""

    measured: SpeedPoint | None = None
    target: SpeedPoint | None = None
    recipe: tuple[SpeedPoint, ...] = ()
    """A recipe's step targets, in order (drawn as a path)."""
    recipe_label: str = "recipe"
    recipe_path: tuple[SpeedPoint, ...] = ()
    """The speeds the planner moves through, corner by corner (one axis after the other), the final stop included."""
    at: tuple[SpeedPoint, ...] = ()
    """Planned points given one by one (``--at``)."""

    @property
    def planned(self) -> tuple[SpeedPoint, ...]:
        """Every planned point: the recipe's, then the ones given one by one."""
        return self.recipe + self.at


def limits_figure(envelope: Envelope, title: str, points: OperatingPoints = OperatingPoints()) -> Figure:
    """The two panels, one above the other, as one matplotlib figure one column wide (not yet written)."""
    from matplotlib import rc_context
    from matplotlib.figure import Figure

    with rc_context(cast("dict[Any, Any]", RC)):  # matplotlib types the keys as a Literal of every rc name
        fig = Figure(figsize=(COLUMN_WIDTH_IN, 10.5), layout="constrained")
        ax_env, ax_phase = fig.subplots(2, 1)
        _envelope_panel(ax_env, envelope, points)
        _phase_panel(ax_phase, envelope)
        p = envelope.params
        fig.suptitle(wrap(
            f"{title}: the safe speeds and cam phases; m = {p.rod_mass_kg * 1e3:.1f} g, r0 = {p.r0_m * 1e3:.1f} mm, "
            f"r_d = {p.eccentricity_m * 1e3:.2f} mm, k = {p.spring_n_per_m:g} N/m, {p.cam.value}-acting cam",
            TITLE_CHARS))
    return fig


def _legend_under(ax: Axes) -> None:
    """The panel's legend right under its x label (a fixed 0.42 in below the axes), entries wrapped to the column."""
    from matplotlib.transforms import ScaledTranslation

    handles, labels = ax.get_legend_handles_labels()
    below = ax.transAxes + ScaledTranslation(0.0, -0.42, ax.get_figure().dpi_scale_trans)  # type: ignore[union-attr]
    ax.legend(handles, [wrap(label, LEGEND_CHARS) for label in labels], loc="upper center",
              bbox_to_anchor=(0.5, 0.0), bbox_transform=below, ncols=1, frameon=False, borderaxespad=0.0)


def _envelope_panel(ax: Axes, envelope: Envelope, points: OperatingPoints) -> None:
    w_v_rpm = np.linspace(0.0, envelope.vibration_max_rpm, 600)
    w_v = rpm_to_rad_s(w_v_rpm)
    limit = envelope.omega_r_limit_rpm(w_v_rpm)
    ax.fill_between(w_v_rpm, 0.0, limit, color="tab:green", alpha=0.25, lw=0,
                    label=f"allowed: {envelope.law.value} − {envelope.margin:.0%} margin (the interlock enforces this)")
    ax.plot(w_v_rpm, limit, color="darkgreen", lw=2.2, label="enforced limit on ω_r")
    for law in LAWS:
        color, style = LAW_STYLE[law]
        words = LAW_IN_WORDS[law] + (" — configured law, no margin" if law is envelope.law else "")
        ax.plot(w_v_rpm, rad_s_to_rpm(omega_r_max(law, envelope.params, w_v)), color=color, ls=style, lw=1.3,
                label=f"{law.value}: {words}")
    warning = regime_warning(envelope)
    if warning is not None:
        ax.axvspan(warning.above_vibration_rpm, envelope.vibration_max_rpm, facecolor="gold", alpha=0.18,
                   hatch="//", edgecolor="goldenrod", lw=0, label=f"⚠ {warning.summary}")
    top = 1.15 * max(float(np.max(limit)), *(pt.omega_r_rpm for pt in _all(points)), 1.0)
    if envelope.rotary_max_rpm <= top:
        ax.axhline(envelope.rotary_max_rpm, color="black", lw=0.8,
                   label=f"rotary drive maximum {envelope.rotary_max_rpm:.0f} rpm")
    _mark_points(ax, envelope, points)
    ax.set(xlabel="vibration speed ω_v (rpm)", ylabel="rotary speed ω_r (rpm)", xlim=(0, envelope.vibration_max_rpm),
           ylim=(0, top), title="Which rotary speed is safe (Fig. 5 counterpart)")
    ax.grid(alpha=0.3)
    _legend_under(ax)


def _all(points: OperatingPoints) -> list[SpeedPoint]:
    return [pt for pt in (points.measured, points.target, *points.planned) if pt is not None]


def _mark_points(ax: Axes, envelope: Envelope, points: OperatingPoints) -> None:
    if points.recipe_path:
        ax.plot([pt.omega_v_rpm for pt in points.recipe_path], [pt.omega_r_rpm for pt in points.recipe_path],
                color="tab:cyan", lw=1.2, label="planned path: the planner's ramps, one drive after the other, "
                "and the final stop")
    if points.recipe:
        ax.plot([pt.omega_v_rpm for pt in points.recipe], [pt.omega_r_rpm for pt in points.recipe],
                ls="", marker="D", ms=4, mfc="white", mec="tab:cyan", label=f"planned: {points.recipe_label}")
    if points.at:
        ax.plot([pt.omega_v_rpm for pt in points.at], [pt.omega_r_rpm for pt in points.at], ls="", marker="s",
                ms=4, mfc="white", mec="tab:blue", label=f"planned: {len(points.at)} point(s) given with --at")
    bad = [pt for pt in points.planned if not envelope.allows(pt.omega_r_rpm, pt.omega_v_rpm)]
    if bad:
        ax.plot([pt.omega_v_rpm for pt in bad], [pt.omega_r_rpm for pt in bad], ls="", marker="X", ms=7,
                color="red", label=f"planned point outside the envelope ({len(bad)}): the interlock refuses it")
    if points.target is not None:
        t = points.target
        ax.plot([t.omega_v_rpm], [t.omega_r_rpm], ls="", marker="o", ms=7, mfc="none", mec="black", mew=1.6,
                label=f"target now: ω_v {t.omega_v_rpm:.0f}, ω_r {t.omega_r_rpm:.0f} rpm")
    if points.measured is not None:
        m = points.measured
        outside = not envelope.allows_measured(m.omega_r_rpm, m.omega_v_rpm)
        ax.plot([m.omega_v_rpm], [m.omega_r_rpm], ls="", marker="o", ms=5, color="red" if outside else "black",
                label=f"measured now: ω_v {m.omega_v_rpm:.0f}, ω_r {m.omega_r_rpm:.0f} rpm"
                + (" — OUTSIDE" if outside else ""))


def _phase_panel(ax: Axes, envelope: Envelope) -> None:
    """The cam phase sin α against ω_v, shaded where eq. 7 has a real detachment angle (docs/model.md, eq. 8b)."""
    p = envelope.params
    w_v_rpm = np.linspace(0.0, envelope.vibration_max_rpm, 600)
    w_v = rpm_to_rad_s(w_v_rpm)
    bound = sin_alpha_bound_consistent(p, w_v)
    stiff = p.spring_n_per_m > p.rod_mass_kg * np.square(lift_speed_array(p.cam, w_v))
    low = np.where(stiff, np.clip(bound, -1.0, 1.0), -1.0)
    high = np.where(stiff, 1.0, np.clip(bound, -1.0, 1.0))
    ax.axhspan(-1.0, 1.0, color="0.6", alpha=0.25, lw=0, label="no real detachment angle at this phase")
    ax.fill_between(w_v_rpm, low, high, color="tab:green", alpha=0.45, lw=0,
                    label="admissible: eq. 7 gives a real detachment angle")
    ax.plot(np.where(stiff, w_v_rpm, np.nan), bound, color="darkgreen", lw=1.4,
            label="from eq. 7: lower bound on sin α (k > mω_v²)")
    ax.plot(np.where(~stiff, w_v_rpm, np.nan), bound, color="darkgreen", lw=1.4, ls="--",
            label="from eq. 7: upper bound on sin α (k < mω_v²)")
    ax.plot(w_v_rpm, sin_alpha_bound_printed_eq8b(p, w_v), color="tab:red", lw=1.0, ls=":",
            label="printed eq. 8b (erratum: inconsistent units, not used)")
    ax.set(xlabel="vibration speed ω_v (rpm)", ylabel="cam phase sin α (–)", ylim=(-1.15, 1.15),
           xlim=(0, envelope.vibration_max_rpm), title="Admissible cam phase (Fig. 6 counterpart)")
    ax.grid(alpha=0.3)
    _legend_under(ax)


def planned_from_recipe(
    path: str, config: MillConfig
) -> tuple[tuple[SpeedPoint, ...], str, tuple[SpeedPoint, ...]]:
    """The target speeds of every step of a recipe's plan, what they are, and the path the planner drives."""
    from millctl.recipes import load_recipe, plan_recipe

    loaded = load_recipe(path)
    plan = plan_recipe(loaded.recipe, config)
    name = loaded.recipe.recipe.name
    label = f"recipe {name}, the target of each of its {len(plan.steps)} steps"
    moves = [step.trajectory for step in plan.steps if step.trajectory is not None] + [plan.stop]
    path_points = [corner for move in moves for corner in move.vertices()]
    route = tuple(p for i, p in enumerate(path_points) if i == 0 or p != path_points[i - 1])
    return tuple(step.target for step in plan.steps), label, route


def planned_from_pairs(pairs: Sequence[Sequence[float]]) -> tuple[SpeedPoint, ...]:
    """``--at VIB ROT`` pairs as speed points."""
    return tuple(SpeedPoint(omega_r_rpm=float(rot), omega_v_rpm=float(vib)) for vib, rot in pairs)


__all__ = ["OperatingPoints", "limits_figure", "planned_from_pairs", "planned_from_recipe"]
