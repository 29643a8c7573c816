"""``millctl recipe check|plan|run``: pre-flight and run milling recipes."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, Any

from millctl.cli.output import hms, print_json, stderr_console, stdout_console
from millctl.cli.recipe_run_cmd import register_run
from millctl.errors import ExitCode, InterlockError

if TYPE_CHECKING:  # the planner loads numba and scipy: only the commands that plan import it
    from millctl.recipes import RecipePlan


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``recipe check``, ``recipe plan`` and ``recipe run``."""
    parser = subparsers.add_parser("recipe", help="check, plan and run milling recipes")
    sub = parser.add_subparsers(dest="recipe_command", metavar="ACTION", required=True)
    check = sub.add_parser(
        "check",
        help="validate a recipe (exit 1 when invalid) and pre-flight it against the envelope "
        "(exit 2 when refused, as every refusal)",
    )
    check.add_argument("--json", action="store_true", help="machine-readable output")
    check.add_argument("file", help="the recipe (TOML)")
    check.set_defaults(handler=_check)
    plan = sub.add_parser("plan", help="the timeline of a recipe: steps, setpoints, margins, expected impacts")
    plan.add_argument("file", help="the recipe (TOML)")
    plan.add_argument("--json", action="store_true", help="machine-readable output")
    plan.set_defaults(handler=_plan)
    register_run(sub)


class PreflightRefused(InterlockError):
    """A valid recipe whose plan leaves the envelope: refused like any command the interlock refuses (exit 2)."""

    def __init__(self, source: str, problems: list[str]) -> None:
        self.source = source
        self.problems = problems
        lines = "\n".join(f"  {p}" for p in problems)
        super().__init__(f"recipe {source} refused by the pre-flight check:\n{lines}")


def preflight(args: argparse.Namespace) -> tuple[Any, RecipePlan]:
    """Load the config and the recipe, and plan it; raise :class:`PreflightRefused` listing every violation."""
    from millctl.config import load_config
    from millctl.recipes import load_recipe, plan_recipe

    config = load_config(args.config).config
    loaded = load_recipe(args.file)
    plan = plan_recipe(loaded.recipe, config)
    if not plan.ok:
        raise PreflightRefused(loaded.source, [f"{loaded.source}: {v} (law {plan.law})" for v in plan.violations])
    return loaded, plan


def _check(args: argparse.Namespace) -> int:
    loaded, plan = preflight(args)
    if args.json:
        print_json(args, plan_as_data(loaded, plan))
        return int(ExitCode.OK)
    stdout_console().print(
        f"{loaded.source}: ok — {len(plan.steps)} steps, {hms(plan.total_s)} planned, "
        f"minimum margin {min(s.min_margin_rpm for s in plan.steps):.1f} rpm under {plan.law}",
        markup=False,
    )
    return int(ExitCode.OK)


def plan_as_data(loaded: Any, plan: RecipePlan) -> dict[str, Any]:
    """The plan as plain data (for --json and the API)."""
    return {
        "recipe": loaded.recipe.recipe.name,
        "source": loaded.source,
        "sha256": loaded.sha256,
        "law": plan.law,
        "margin": plan.margin,
        "total_s": plan.total_s,
        "stop_s": plan.stop.duration_s,
        "powder_charge_g": plan.powder_charge_g,
        "total_dose_kj_g": plan.total_dose_kj_g,
        "steps": [
            {
                "index": s.index,
                "kind": s.kind,
                "start_s": s.start_s,
                "duration_s": s.duration_s,
                "open_ended": s.open_ended,
                "rotary_rpm": s.target.omega_r_rpm,
                "vibration_rpm": s.target.omega_v_rpm,
                "furnace_c": s.furnace_c,
                "min_margin_rpm": None if math.isinf(s.min_margin_rpm) else s.min_margin_rpm,
                "note": s.note,
                "detached": s.physics.detached if s.physics else None,
                "impact_rate_mill_hz": _mill_rate(plan, s),
                "impact_rate_per_rod_hz": _per_rod(_mill_rate(plan, s), plan.n_rods),
                "impact_energy_mj": s.physics.mean_impact_energy_j * 1e3 if s.physics else None,
                "dose_kj_g": s.dose_kj_g,
                "dose_target_kj_g": s.dose_target_kj_g,
            }
            for s in plan.steps
        ],
    }


def _plan(args: argparse.Namespace) -> int:
    loaded, plan = preflight(args)
    data = plan_as_data(loaded, plan)
    if args.json:
        print_json(args, data)
        return int(ExitCode.OK)
    from rich.table import Table

    table = Table(title=f"{data['recipe']} — law {plan.law}, margin {plan.margin:.0%}")
    columns = (
        "#",
        "kind",
        "start",
        "duration",
        "ω_r rpm",
        "ω_v rpm",
        "furnace °C",
        "min margin rpm",
        "impacts/s mill",
        "impacts/s rod",
        "energy mJ",
        "dose kJ/g",
        "note",
    )
    for name in columns:
        table.add_column(name, justify="left" if name in ("kind", "note") else "right")
    for s in data["steps"]:
        table.add_row(
            str(s["index"]),
            s["kind"],
            hms(s["start_s"]),
            "open" if s["open_ended"] else hms(s["duration_s"]),
            f"{s['rotary_rpm']:.1f}",
            f"{s['vibration_rpm']:.1f}",
            "off" if s["furnace_c"] is None else f"{s['furnace_c']:.0f}",
            "standstill" if s["min_margin_rpm"] is None else f"{s['min_margin_rpm']:.1f}",
            _physics_cell(s["detached"], s["impact_rate_mill_hz"], "{:.1f}"),
            _physics_cell(s["detached"], s["impact_rate_per_rod_hz"], "{:.2f}"),
            _physics_cell(s["detached"], s["impact_energy_mj"], "{:.2f}"),
            _dose_cell(s["dose_kj_g"], s["dose_target_kj_g"]),
            s["note"],
        )
    table.caption = (
        f"final stop {hms(plan.stop.duration_s)}; total {hms(plan.total_s)} (open-ended steps not counted); "
        f"expected dose {plan.total_dose_kj_g:.3g} kJ/g of {plan.powder_charge_g:g} g powder, whole mill "
        f"({plan.n_rods} rods: impacts/s mill = {plan.n_rods} × impacts/s rod)"
    )
    stdout_console().print(table)
    stderr_console().print(f"{loaded.source}: sha256 {loaded.sha256[:16]}")
    return int(ExitCode.OK)


def _mill_rate(plan: RecipePlan, step: Any) -> float | None:
    """The whole mill's impact rate at a step (Hz): the one its dose is computed with (physics.dose)."""
    from millctl.config import ModelVariant
    from millctl.physics.dose import whole_mill_rate_hz

    if step.physics is None:
        return None
    return whole_mill_rate_hz(ModelVariant(plan.variant), plan.n_rods, step.physics.impact_rate_hz)


def _per_rod(rate_hz: float | None, n_rods: int) -> float | None:
    return None if rate_hz is None else rate_hz / n_rods


def _dose_cell(dose_kj_g: float, target_kj_g: float | None) -> str:
    """Expected dose of a step; a dose-targeted hold shows its target."""
    return f"{dose_kj_g:.3g}" if target_kj_g is None else f"{dose_kj_g:.3g} (until {target_kj_g:g})"


def _physics_cell(detached: bool | None, value: float | None, fmt: str) -> str:
    if detached is None or value is None:
        return "—"
    return fmt.format(value) if detached else "pinned"
