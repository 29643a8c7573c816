"""``millctl limits``: ω_r,max against ω_v for every detachment law, with regime flags."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from millctl.cli.args import nonnegative_float
from millctl.cli.output import print_json, stderr_console, stdout_console, write_atomically
from millctl.config import CamShape, LimitLaw, load_config
from millctl.errors import ExitCode, InvalidInputError
from millctl.physics.limits import (
    LAWS,
    omega_r_max,
    regime_flags,
    sin_alpha_bound_consistent,
    sin_alpha_bound_printed_eq8b,
    switch_omega_v_rad_s,
    vibration_intensity,
)
from millctl.safety import Envelope
from millctl.units import rad_s_to_rpm, rpm_to_rad_s


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``limits``."""
    parser = subparsers.add_parser(
        "limits",
        help="table (and plot) of the maximum rotary speed against vibration speed",
        description="ω_r,max against ω_v for every detachment law, the enforced envelope and the regime flags.",
    )
    parser.add_argument(
        "--vib-rpm",
        type=nonnegative_float,
        nargs="+",
        metavar="RPM",
        help="vibration speeds (default: 0 to the drive's maximum in 100 rpm steps)",
    )
    parser.add_argument(
        "--law",
        choices=[law.value for law in LimitLaw],
        help="law for the envelope column (default: the configured interlock law)",
    )
    parser.add_argument(
        "--cam",
        choices=[c.value for c in CamShape],
        help="cam shape (default: the configured one); with it, the two cams compared at the same speeds",
    )
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.add_argument(
        "--plot",
        metavar="FILE.png",
        type=Path,
        help="draw the counterparts of the paper's Fig. 5 and Fig. 6 (needs the plot extra)",
    )
    parser.set_defaults(handler=_run)


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
        "rows": rows,
    }


def _run(args: argparse.Namespace) -> int:
    table = limits_table(args)
    if args.cam:
        from millctl.studies.cams import compare_cams

        config = load_config(args.config).config
        speeds = [row["vibration_rpm"] for row in table["rows"]]
        table["cams"] = compare_cams(config, LimitLaw(table["law"]), speeds)
    if args.plot:
        plot_limits(args.plot, table, args)
    if args.json:
        print_json(args, table)
    else:
        _print_table(table)
        if "cams" in table:
            _print_cams(table)
    not_every = [r["vibration_rpm"] for r in table["rows"] if not r["law_is_every_cycle"]]
    if not_every:
        stderr_console().print(
            f"[yellow]warning:[/] the configured law {table['law']} is not the every-cycle detachment bound "
            f"at ω_v = {', '.join(f'{v:g}' for v in not_every)} rpm (k < mω_v² above "
            f"{table['switch_vibration_rpm']:.1f} rpm): rods may stay pinned for many cycles there. "
            "See docs/model.md#eq-9."
        )
    return int(ExitCode.OK)


_SHORT_HEADER = {
    LimitLaw.PAPER_EQ9: "eq. 9\nprinted",
    LimitLaw.PAPER_EVERY_CYCLE: "paper\nworst φ",
    LimitLaw.CORRECTED_EVERY_PHASE: "corr.\nevery φ",
    LimitLaw.CORRECTED_BEST_PHASE: "corr.\nbest φ",
}
_FLAGS = (("no-lim", "no_real_limit"), ("k<mω²", "spring_below_inertia"), ("Γ≥1", "gamma_ge_1"))


def _print_table(table: dict[str, Any]) -> None:
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
    out.caption = (
        "† the envelope's law is not the every-cycle bound here; "
        "k<mω²: printed eq. 9 is not the worst phase; Γ≥1: cam acceleration ≥ g; "
        "no-lim: no real limit, standstill only"
    )
    stdout_console().print(out)


def _print_cams(table: dict[str, Any]) -> None:
    from rich.table import Table

    out = Table(title=f"single- against double-acting cam under {table['law']}: impacts per rod and revolution p")
    for name in ("ω_v rpm", "envelope\nsingle", "envelope\ndouble", "at ω_r"):
        out.add_column(name, justify="right")
    for variant in ("paper", "corrected"):
        for shape in ("single", "double"):
            out.add_column(f"p {variant}\n{shape}", justify="right")
        out.add_column(f"{variant}\ndouble/single", justify="right")
    for row in table["cams"]:
        cells = [f"{row['vibration_rpm']:.0f}", f"{row['limit_rotary_single_rpm']:.1f}"]
        cells += [f"{row['limit_rotary_double_rpm']:.1f}", f"{row['rotary_rpm']:.1f}"]
        for variant in ("paper", "corrected"):
            single, double = row[f"p_{variant}_single"], row[f"p_{variant}_double"]
            cells += [_num(single), _num(double), _num(double / single if single > 0 else float("nan"))]
        out.add_row(*cells)
    out.caption = "p at the highest ω_r both envelopes allow (level-(b) summaries, 16 cam phases); — none"
    stdout_console().print(out)


def _num(value: float) -> str:
    return "—" if not np.isfinite(value) else f"{value:.3f}"


def plot_limits(path: Path, table: dict[str, Any], args: argparse.Namespace) -> None:
    """Write the Fig. 5 and Fig. 6 counterparts into one PNG (atomically)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise InvalidInputError("--plot needs matplotlib: pip install 'millctl[plot]'") from None
    if not path.parent.exists():
        raise InvalidInputError(f"--plot {path}: directory {path.parent} does not exist")
    config = load_config(args.config).config
    if args.cam:
        from millctl.studies.cams import with_cam

        config = with_cam(config, CamShape(args.cam))
    p = Envelope.from_config(config).params
    w_v_rpm = np.linspace(0.0, config.drives.vibration.max_speed_rpm, 400)
    w_v = rpm_to_rad_s(w_v_rpm)
    fig, (ax5, ax6) = plt.subplots(1, 2, figsize=(12, 4.8), layout="constrained")
    for law in LAWS:
        ax5.plot(w_v_rpm, rad_s_to_rpm(omega_r_max(law, p, w_v)), label=law.value)
    law = LimitLaw(table["law"])
    envelope = Envelope.from_config(config, law=law)
    ax5.fill_between(
        w_v_rpm,
        0,
        envelope.omega_r_limit_rpm(w_v_rpm),
        color="tab:green",
        alpha=0.12,
        label=f"envelope ({law.value}, margin {envelope.margin:.0%})",
    )
    ax5.axvline(table["switch_vibration_rpm"], color="grey", ls=":", label="k = mω_v²")
    ax5.set(
        xlabel="vibration speed ω_v (rpm)",
        ylabel="max rotary speed ω_r,max (rpm)",
        title="Fig. 5 counterpart: maximum permissible rotary speed",
    )
    ax5.legend(fontsize=8)
    ax5.grid(alpha=0.3)
    ax6.plot(w_v_rpm, sin_alpha_bound_printed_eq8b(p, w_v), label="printed eq. 8b (inconsistent units)")
    bound = sin_alpha_bound_consistent(p, w_v)
    stiff = p.spring_n_per_m > p.rod_mass_kg * w_v**2
    ax6.plot(np.where(stiff, w_v_rpm, np.nan), bound, label="from eq. 7: lower bound on sin α (k > mω_v²)")
    ax6.plot(np.where(~stiff, w_v_rpm, np.nan), bound, label="from eq. 7: upper bound on sin α (k < mω_v²)")
    ax6.axhspan(-1, 1, color="grey", alpha=0.08, label="sin α ∈ [−1, 1]")
    ax6.set(
        xlabel="vibration speed ω_v (rpm)",
        ylabel="bound on sin α",
        ylim=(-12, 4),
        title="Fig. 6 counterpart: admissible cam phase",
    )
    ax6.legend(fontsize=8)
    ax6.grid(alpha=0.3)
    fig.suptitle(
        f"{config.name}: m = {p.rod_mass_kg * 1e3:.1f} g, r0 = {p.r0_m * 1e3:.1f} mm, "
        f"r_d = {p.eccentricity_m * 1e3:.2f} mm, k = {p.spring_n_per_m:g} N/m"
    )
    write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=120, format="png"))
    plt.close(fig)
    stderr_console().print(f"wrote {path}")
