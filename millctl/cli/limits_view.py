"""``millctl limits``'s work: the table of ω_r,max against ω_v for every law, its printing and its plot.

Loaded by :mod:`millctl.cli.limits_cmd` when the command runs (numpy, the physics, the configuration models).
"""

from __future__ import annotations

import argparse
import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from millctl.cli.output import stderr_console, stdout_console, write_atomically
from millctl.config import CamShape, LimitLaw, load_config
from millctl.errors import InvalidInputError
from millctl.physics.limits import (
    LAWS,
    omega_r_max,
    regime_flags,
    switch_omega_v_rad_s,
    vibration_intensity,
)
from millctl.safety import Envelope, SpeedPoint
from millctl.safety.regime import regime_warning
from millctl.units import rad_s_to_rpm, rpm_to_rad_s


def limits_table(args: argparse.Namespace) -> dict[str, Any]:
    """Compute the limits table as plain data."""
    loaded = load_config(args.config)
    config = loaded.config
    if getattr(args, "cam", None):
        from millctl.studies.cams import with_cam

        config = with_cam(config, CamShape(args.cam))
    envelope = Envelope.from_config(config, law=LimitLaw(args.law) if args.law else None)
    vib_max = config.drives.vibration.max_speed_rpm
    omega_v_rpm = np.array(args.vib_rpm) if args.vib_rpm else np.arange(0.0, vib_max + 1e-9, 100.0)
    omega_v = rpm_to_rad_s(omega_v_rpm)
    p = envelope.params
    flags = regime_flags(envelope.law, p, omega_v)
    laws = {law.value: rad_s_to_rpm(omega_r_max(law, p, omega_v)) for law in LAWS}
    envelope_rpm = envelope.omega_r_limit_rpm(omega_v_rpm)
    warning = regime_warning(envelope)
    every_cycle = envelope.every_cycle(omega_v_rpm)
    gamma = vibration_intensity(p, omega_v)
    rows = []
    for i, w_v in enumerate(omega_v_rpm):
        rows.append(
            {
                "vibration_rpm": float(w_v),
                "gamma": float(gamma[i]),
                "law_limit_rotary_rpm": {name: float(values[i]) for name, values in laws.items()},
                "limit_rotary_rpm": float(envelope_rpm[i]),
                "law_is_every_cycle": bool(every_cycle[i]),
                "no_real_limit": bool(flags.no_real_limit[i]),
                "spring_below_inertia": bool(flags.spring_below_inertia[i]),
                "gamma_ge_1": bool(flags.gamma_ge_1[i]),
                "over_drive_limit": bool(w_v > vib_max),
            }
        )
    return {
        "config": loaded.source,
        "law": envelope.law.value,
        "margin": envelope.margin,
        "rod_mass_kg": p.rod_mass_kg,
        "switch_vibration_rpm": float(rad_s_to_rpm(switch_omega_v_rad_s(p))),
        "cam": config.mill.cam.shape.value,
        "regime": None
        if warning is None
        else {
            "above_vibration_rpm": warning.above_vibration_rpm,
            "summary": warning.summary,
            "message": warning.message,
        },
        "rows": rows,
    }


def cams_table(args: argparse.Namespace, table: dict[str, Any]) -> list[dict[str, Any]]:
    """The single- and double-acting cams compared at the table's speeds, under its law."""
    from millctl.studies.cams import compare_cams

    config = load_config(args.config).config
    speeds = [row["vibration_rpm"] for row in table["rows"]]
    return compare_cams(config, LimitLaw(table["law"]), speeds)


_SHORT_HEADER = {
    LimitLaw.PAPER_EQ9: "eq. 9\nprinted",
    LimitLaw.PAPER_EVERY_CYCLE: "paper\nworst φ",
    LimitLaw.CORRECTED_EVERY_PHASE: "corr.\nevery φ",
    LimitLaw.CORRECTED_BEST_PHASE: "corr.\nbest φ",
}
_FLAGS = (("no-lim", "no_real_limit"), ("k<mω²", "spring_below_inertia"), ("Γ≥1", "gamma_ge_1"))


def print_table(table: dict[str, Any]) -> None:
    """The table on stdout, one row a vibration speed."""
    from rich.table import Table

    out = Table(title=f"ω_r,max (rpm) against ω_v; envelope = {table['law']}, margin {table['margin']:.0%}")
    out.add_column("ω_v rpm", justify="right")
    out.add_column("Γ", justify="right")
    for law in LAWS:
        out.add_column(_SHORT_HEADER[law], justify="right")
    out.add_column("envelope", justify="right")
    out.add_column("flags")
    for row in table["rows"]:
        flags = [name for name, key in _FLAGS if row[key]]
        if not row["law_is_every_cycle"]:
            flags.append("†")
        out.add_row(
            f"{row['vibration_rpm']:.0f}",
            f"{row['gamma']:.3f}",
            *(f"{row['law_limit_rotary_rpm'][law.value]:.1f}" for law in LAWS),
            f"{row['limit_rotary_rpm']:.1f}",
            " ".join(flags),
        )
    console = stdout_console()
    out.caption = "\n".join(textwrap.wrap(  # a console that soft-wraps would print it on one line
        "† the envelope's law is not the every-cycle bound here; "
        "k<mω²: printed eq. 9 is not the worst phase; Γ≥1: cam acceleration ≥ g; "
        "no-lim: no real limit, standstill only", console.width))
    console.print(out)


def print_cams(table: dict[str, Any]) -> None:
    """The cams' comparison on stdout."""
    from millctl.cli.tables import Column
    from millctl.cli.tables import print_table as print_columns

    rows = table["cams"]

    def column(header: str, cells: list[str]) -> Column:
        return Column(header, tuple(cells))

    columns = [
        column("ω_v (rpm)", [f"{r['vibration_rpm']:.0f}" for r in rows]),
        column("envelope, single cam (rpm)", [f"{r['limit_rotary_single_rpm']:.1f}" for r in rows]),
        column("envelope, double cam (rpm)", [f"{r['limit_rotary_double_rpm']:.1f}" for r in rows]),
        column("at ω_r (rpm)", [f"{r['rotary_rpm']:.1f}" for r in rows]),
    ]
    for variant in ("paper", "corrected"):
        single = [r[f"p_{variant}_single"] for r in rows]
        double = [r[f"p_{variant}_double"] for r in rows]
        columns += [
            column(f"p, {variant}, single cam", [_num(v) for v in single]),
            column(f"p, {variant}, double cam", [_num(v) for v in double]),
            column(f"p, {variant}, double/single",
                   [_num(d / s if s > 0 else float("nan")) for s, d in zip(single, double, strict=True)]),
        ]
    print_columns(
        stdout_console(),
        f"single- against double-acting cam under {table['law']}: impacts per rod and revolution p",
        columns,
        caption="p at the highest ω_r both envelopes allow (level-(b) summaries, 16 cam phases); — none",
    )


def _num(value: float) -> str:
    return "—" if not np.isfinite(value) else f"{value:.3f}"


def plot_limits(path: Path, table: dict[str, Any], args: argparse.Namespace) -> None:
    """Write the envelope figure (:mod:`millctl.cli.limits_plot`) into one PNG, atomically."""
    try:
        import matplotlib

        matplotlib.use("Agg")
    except ImportError:
        raise InvalidInputError("--plot needs matplotlib: pip install 'millctl[plot]'") from None
    from millctl.cli.limits_plot import OperatingPoints, limits_figure, planned_from_pairs, planned_from_recipe

    if not path.parent.exists():
        raise InvalidInputError(f"--plot {path}: directory {path.parent} does not exist")
    config = load_config(args.config).config
    if args.cam:
        from millctl.studies.cams import with_cam

        config = with_cam(config, CamShape(args.cam))
    envelope = Envelope.from_config(config, law=LimitLaw(table["law"]))
    recipe, label, route = planned_from_recipe(args.recipe, config) if args.recipe else ((), "", ())
    measured, target = _live_points(args) if args.live else (None, None)
    points = OperatingPoints(measured, target, recipe=recipe, recipe_label=label, recipe_path=route,
                             at=planned_from_pairs(args.at or []))
    fig = limits_figure(envelope, config.name, points)
    write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=300, format="png", bbox_inches="tight"))
    stderr_console().print(f"wrote {path}")


def _live_points(args: argparse.Namespace) -> tuple[SpeedPoint | None, SpeedPoint | None]:
    """The running service's measured speeds and target (None where it has none yet)."""
    from millctl.client import Client

    with Client(args.socket, config=args.config, name="cli-limits") as client:
        status = client.status()
    measured = target = None
    if status.measured_rotary_rpm is not None and status.measured_vibration_rpm is not None:
        measured = SpeedPoint(status.measured_rotary_rpm, status.measured_vibration_rpm)
    if status.target_rotary_rpm is not None and status.target_vibration_rpm is not None:
        target = SpeedPoint(status.target_rotary_rpm, status.target_vibration_rpm)
    return measured, target


__all__ = ["cams_table", "limits_table", "plot_limits", "print_cams", "print_table"]
