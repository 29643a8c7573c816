"""``millctl config show|check``: print or validate a mill configuration."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from millctl.cli.output import print_json, stdout_console
from millctl.errors import ExitCode

if TYPE_CHECKING:
    from millctl.config import MillConfig
    from millctl.config.loader import LoadedConfig


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``config show`` and ``config check``."""
    parser = subparsers.add_parser("config", help="show or check a mill configuration")
    sub = parser.add_subparsers(dest="config_command", metavar="ACTION", required=True)
    show = sub.add_parser("show", help="print the configuration in force and where it came from")
    show.add_argument("--json", action="store_true", help="machine-readable output")
    show.set_defaults(handler=_show)
    check = sub.add_parser("check", help="validate a configuration file (exit 1 when invalid)")
    check.add_argument("file", help="the TOML file to check")
    check.set_defaults(handler=_check)


def _show(args: argparse.Namespace) -> int:
    from millctl.cli.config_toml import chosen_by, origins, render
    from millctl.config import load_config

    loaded = load_config(args.config)
    conventions = _conventions(loaded)
    if args.json:
        print_json(args, {"source": loaded.source, "chosen_by": chosen_by(args.config), "sha256": loaded.sha256,
                          "config": loaded.config.model_dump(mode="json"), "origin": origins(loaded),
                          "conventions": conventions})
        return int(ExitCode.OK)
    stdout_console().print(render(loaded, args.config, conventions), markup=False, end="")
    return int(ExitCode.OK)


def _conventions(loaded: LoadedConfig) -> dict[str, str]:
    """What an empty socket_path / records_dir becomes, and from which environment (docs/deployment.md)."""
    from millctl.config.paths import service_paths

    paths = service_paths(loaded)
    found = {}
    if not loaded.config.service.socket_path:
        found["service.socket_path"] = f"by convention: {paths.socket} ({paths.socket_from})"
    if not loaded.config.service.records_dir:
        found["service.records_dir"] = f"by convention: {paths.records_dir}"
    return found


def _check(args: argparse.Namespace) -> int:
    from millctl.config import load_config

    loaded = load_config(args.file)
    warnings = config_warnings(loaded.config)
    if args.json:
        print_json(args, {"source": loaded.source, "name": loaded.config.name, "sha256": loaded.sha256,
                          "warnings": warnings})
        return int(ExitCode.OK)
    console = stdout_console()
    console.print(f"{loaded.source}: ok ({loaded.config.name})", markup=False)
    for warning in warnings:
        console.print(f"[yellow]warning:[/] {warning}")
    return int(ExitCode.OK)


def config_warnings(config: MillConfig) -> list[str]:
    """Valid but suspicious settings, each with its number: k that makes printed eq. 9 vacuous."""
    from millctl.physics.limits import LimitParams, eq9_vacuous_below_rad_s
    from millctl.units import rad_s_to_rpm

    params = LimitParams.from_config(config)
    vacuous_rpm = rad_s_to_rpm(eq9_vacuous_below_rad_s(params))
    if vacuous_rpm <= 0.0:
        return []
    drive_max = config.drives.vibration.max_speed_rpm
    reach = "the whole vibration drive range" if vacuous_rpm >= drive_max else "part of the drive range"
    return [
        f"k = {params.spring_n_per_m:g} N/m makes printed eq. 9 vacuous: its numerator m g − (k − m ω_v²) r_d "
        f"is ≤ 0 for ω_v ≤ {vacuous_rpm:.1f} rpm ({reach}, max {drive_max:g} rpm), where the paper's laws "
        "admit no rotation; k is a per-rod effective stiffness (Set A 92 N/m), not the platform springs' rate "
        "(docs/model.md, errata k)"
    ]
