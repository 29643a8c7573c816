"""``millctl physics``: first detachment, flight and first impact of the configured mill, and its telemetry."""

from __future__ import annotations

import argparse
import dataclasses
import math
from typing import Any

from millctl.cli.args import finite_float, nonnegative_float
from millctl.cli.output import print_json, stdout_console
from millctl.errors import ExitCode


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``physics``."""
    parser = subparsers.add_parser(
        "physics",
        help="first detachment, flight and first impact at given speeds, and the per-revolution summary",
        description=(
            "Run the physics engine (docs/model.md) for the configured mill: the first detachment "
            "(or that the rods stay pinned), the flight time, the first impact and the level-(b) summary."
        ),
    )
    parser.add_argument("--rot-rpm", type=nonnegative_float, required=True, metavar="RPM", help="vial speed ω_r")
    parser.add_argument("--vib-rpm", type=nonnegative_float, required=True, metavar="RPM", help="cam speed ω_v")
    parser.add_argument("--variant", choices=["paper", "corrected"], help="physics (default: the configured one)")
    parser.add_argument(
        "--theta0-deg", type=finite_float, default=-90.0, help="rod 0's initial angle (default −90, bottom)"
    )
    parser.add_argument("--alpha0-deg", type=finite_float, default=0.0, help="initial cam phase (default 0)")
    parser.add_argument(
        "--method",
        choices=["exact", "exact-reference", "legacy", "legacy-interp", "legacy-arcs", "legacy-compiled", "ivp"],
        default="exact",
        help="collision scheme (exact: compiled; exact-reference: the numpy engine; legacy: the paper's fixed step)",
    )
    parser.add_argument(
        "--dt", type=nonnegative_float, default=1e-4, metavar="S", help="legacy time step (default 1e-4 s)"
    )
    parser.add_argument("--q", type=int, default=360, help="legacy-arcs: number of wall arcs (default 360)")
    parser.add_argument(
        "--slip",
        choices=["locked", "free"],
        help="also ride rod 0 with Coulomb slip on the wall (spin locked: the paper's premise; free: it may roll)",
    )
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.set_defaults(handler=_run)


def physics_report(args: argparse.Namespace) -> dict[str, Any]:
    """Compute the report as plain data."""
    from millctl.config import ModelVariant, load_config
    from millctl.physics.methods import first_impact
    from millctl.physics.model import MillModel, Scene
    from millctl.physics.simulate import simulate
    from millctl.physics.slip import no_slip_check
    from millctl.physics.telemetry import revolution_summary
    from millctl.units import rpm_to_rad_s

    loaded = load_config(args.config)
    model = MillModel.from_config(loaded.config)
    if args.variant:
        model = dataclasses.replace(model, variant=ModelVariant(args.variant))
    w_r, w_v = rpm_to_rad_s(args.rot_rpm), rpm_to_rad_s(args.vib_rpm)
    scene = Scene(model, w_r, w_v, math.radians(args.theta0_deg), math.radians(args.alpha0_deg))
    run = simulate(scene, 5.0, stop_after_first=True)
    detachment = None
    if len(run.detachments):
        d = run.detachments[0]
        detachment = {
            "rod": int(d["rod"]),
            "time_s": float(d["time_s"]),
            "theta_d_deg": math.degrees(float(d["theta_rad"])),
            "alpha_d_deg": math.degrees(float(d["alpha_rad"])),
        }
    kwargs: dict[str, Any] = {}
    if args.method.startswith("legacy"):
        kwargs["dt"] = args.dt
    if args.method == "legacy-arcs":
        kwargs["q"] = args.q
    event = first_impact(scene, args.method, **kwargs)
    impact = None
    if event is not None:
        departed = {int(r["rod"]): float(r["time_s"]) for r in run.detachments}
        t_d = departed.get(event.rod, math.nan)
        impact = {
            "rod": event.rod,
            "partner": "wall" if event.partner < 0 else f"rod {event.partner}",
            "time_s": event.time_s,
            # exact: the flight's own clock; the stepped methods only have absolute times
            "flight_time_s": event.flight_time_s if math.isfinite(event.flight_time_s) else event.time_s - t_d,
            "contact_x_m": event.x_m,
            "contact_y_m": event.y_m,
            "normal_velocity_m_s": event.normal_velocity_m_s,
            "tangential_velocity_m_s": event.tangential_velocity_m_s,
            "energy_j": event.energy_j,
        }
    summary = revolution_summary(model, w_r, w_v)
    check = no_slip_check(scene)  # rod 0's carried arc, up to its first detachment (or one revolution)
    no_slip = {
        "violated": check.violated,
        "friction": check.friction,
        "onset_time_s": check.onset_time_s if check.violated else None,
        "onset_theta_deg": math.degrees(check.onset_theta_rad) if check.violated else None,
        "onset_alpha_deg": math.degrees(check.onset_alpha_rad) if check.violated else None,
        "arc_end_s": check.arc_end_s,
        "detached": check.detached,
    }
    return {
        "slip_ride": _slip_ride(scene, args.slip) if args.slip else None,
        "config": loaded.source,
        "variant": model.variant.value,
        "method": args.method,
        "rotary_rpm": args.rot_rpm,
        "vibration_rpm": args.vib_rpm,
        "theta0_deg": args.theta0_deg,
        "alpha0_deg": args.alpha0_deg,
        "pinned": detachment is None,
        "first_detachment": detachment,
        "first_impact": impact,
        "no_slip": no_slip,
        "summary": {
            k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in dataclasses.asdict(summary).items()
        },
    }


def _slip_ride(scene: Any, spin: str) -> dict[str, Any]:
    """Rod 0's ride with Coulomb slip (millctl.physics.slip_ride) and its flight to the wall, as plain data."""
    from millctl.physics.slip_ride import fly_to_wall, ride

    r = ride(scene, "locked" if spin == "locked" else "free")
    landing = fly_to_wall(scene, r.time_s, r.theta_rad, r.theta_rate_rad_s) if r.detached else None
    return {
        "spin": spin,
        "friction": scene.model.powder_friction,
        "detached": r.detached,
        "time_s": r.time_s if r.detached else None,
        "theta_d_deg": math.degrees(r.theta_rad) if r.detached else None,
        "theta_rate_rad_s": r.theta_rate_rad_s if r.detached else None,
        "spin_rad_s": r.spin_rad_s if r.detached else None,
        "sliding_s": r.slip_time_s,
        "mode_changes": len(r.phases),
        "flight_time_s": landing.flight_time_s if landing else None,
        "energy_j": landing.energy_j if landing else None,
    }


def _run(args: argparse.Namespace) -> int:
    report = physics_report(args)
    if args.json:
        print_json(args, report)
        return int(ExitCode.OK)
    out = stdout_console()
    out.print(
        f"{report['variant']} physics, {report['method']} events: ω_r = {report['rotary_rpm']:g} rpm, "
        f"ω_v = {report['vibration_rpm']:g} rpm, θ0 = {report['theta0_deg']:g}°, α0 = {report['alpha0_deg']:g}°"
    )
    det = report["first_detachment"]
    if det is None:
        out.print("first detachment: none within 5 s — the rods stay pinned to the wall")
    else:
        unsupported = " (it starts where N ≤ 0)" if det["time_s"] == 0.0 else ""
        out.print(
            f"first detachment: rod {det['rod']} at t = {det['time_s']:.6f} s, "
            f"θ_d = {det['theta_d_deg']:.3f}°, α_d = {det['alpha_d_deg']:.3f}°{unsupported}"
        )
    imp = report["first_impact"]
    if imp is None:
        out.print("first impact: none")
    else:
        out.print(f"flight time: {imp['flight_time_s'] * 1e3:.4f} ms (rod {imp['rod']})")
        out.print(
            f"first impact: rod {imp['rod']} on the {imp['partner']} at t = {imp['time_s']:.6f} s, contact "
            f"({imp['contact_x_m'] * 1e3:.3f}, {imp['contact_y_m'] * 1e3:.3f}) mm, "
            f"v_n = {imp['normal_velocity_m_s']:.4f} m/s, energy = {imp['energy_j'] * 1e3:.4f} mJ"
        )
    ns = report["no_slip"]
    if ns["violated"]:
        end = "detachment" if ns["detached"] else "the end of the revolution"
        out.print(
            f"[yellow]no-slip violated:[/] rod 0 needs |F_t|/N > μ = {ns['friction']:g} "
            f"from t = {ns['onset_time_s']:.6f} s, θ = {ns['onset_theta_deg']:.2f}°, α = {ns['onset_alpha_deg']:.2f}° "
            f"until {end} at t = {ns['arc_end_s']:.6f} s (the wall cannot carry it: it slides; docs/model.md, slip)"
        )
    else:
        out.print(f"no-slip holds: |F_t|/N ≤ μ = {ns['friction']:g} on rod 0's carried arc")
    sr = report["slip_ride"]
    if sr is not None:
        head = f"slip ride (spin {sr['spin']}, μ = {sr['friction']:g}, rod 0 alone): "
        if not sr["detached"]:
            out.print(head + f"stays on the wall for a revolution, sliding {sr['sliding_s'] * 1e3:.1f} ms of it")
        else:
            landing = (
                "no landing within 2 s"
                if sr["flight_time_s"] is None
                else f"flight {sr['flight_time_s'] * 1e3:.4f} ms, wall impact {sr['energy_j'] * 1e3:.4f} mJ"
            )
            out.print(
                head + f"detaches at t = {sr['time_s']:.6f} s, θ_d = {sr['theta_d_deg']:.3f}° after sliding "
                f"{sr['sliding_s'] * 1e3:.1f} ms; {landing}"
            )
    s = report["summary"]
    theta = "—" if s["theta_d_rad"] is None else f"{math.degrees(s['theta_d_rad']):.2f}°"
    out.print(
        f"per revolution: {'detached' if s['detached'] else 'pinned'}, θ_d = {theta}, "
        f"impacts {s['impact_rate_hz']:.3f} Hz, mean energy {s['mean_impact_energy_j'] * 1e3:.4f} mJ, "
        f"power {s['impact_power_w'] * 1e3:.4f} mW, mean shear {s['mean_shear_pa'] / 1e6:.3f} MPa"
    )
    return int(ExitCode.OK)
