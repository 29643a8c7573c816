"""A recipe at a study's chosen point: ramp there, mill for a dose or a time, stop; pre-flighted before it is written.

The recipe is checked with :func:`~millctl.recipes.plan_recipe` against the
point's own configuration (the base mill with the point's design parameters),
exactly as ``millctl recipe check`` would; a recipe that fails is not written.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from millctl.cli.output import write_atomically
from millctl.errors import InterlockError
from millctl.recipes.plan import plan_recipe
from millctl.recipes.schema import Recipe
from millctl.studies.engine import CONFIG_PATHS, point_config
from millctl.studies.schema import Study

DEFAULT_HOLD_H = 1.0


def _toml_value(value: Any) -> str:
    return json.dumps(value, ensure_ascii=False) if isinstance(value, str) else repr(value)


def recipe_text(study: Study, best: dict[str, Any], powder_g: float, dose_kj_g: float | None, hold_h: float) -> str:
    """The recipe file's text."""
    w_r, w_v = float(best["rotary_rpm"]), float(best["vibration_rpm"])
    design = {k: best[k] for k in CONFIG_PATHS if k in best}
    hold = f"dose_kj_g = {dose_kj_g!r}" if dose_kj_g is not None else f"duration_h = {hold_h!r}"
    note = "; ".join(f"{k} = {v}" for k, v in design.items())
    lines = [
        f"# Written by `millctl study` from {study.study.name!r}, point {best['point']}.",
        "# Pre-flighted against the point's configuration" + (f" (design: {note})." if note else " (the base mill)."),
        "[recipe]",
        f"name = {_toml_value(f'{study.study.name}: {w_r:.1f}/{w_v:.1f} rpm')}",
        f"powder_charge_g = {powder_g!r}",
        f"operator_note = {_toml_value('study optimum' + (f'; the mill must have {note}' if note else ''))}",
        "",
        "[[steps]]",
        'kind = "ramp"',
        f"rotary_rpm = {w_r!r}",
        f"vibration_rpm = {w_v!r}",
        "",
        "[[steps]]",
        'kind = "hold"',
        hold,
        "",
        "[[steps]]",
        'kind = "ramp"',
        "rotary_rpm = 0.0",
        "vibration_rpm = 0.0",
        "",
    ]
    return "\n".join(lines)


def write_recipe(
    path: Path, study: Study, runner: Any, best: dict[str, Any], dose_kj_g: float | None, hold_h: float | None
) -> dict[str, Any]:
    """Write the pre-flighted recipe at the best point; raise InterlockError (nothing written) if it fails."""
    import tomllib

    config = point_config(runner.task({p.value: best[p.value] for p in study.parameters}))
    text = recipe_text(study, best, config.mill.powder.charge_g, dose_kj_g, hold_h or DEFAULT_HOLD_H)
    recipe = Recipe.model_validate(tomllib.loads(text))
    plan = plan_recipe(recipe, config)
    if not plan.ok:
        problems = "; ".join(str(v) for v in plan.violations)
        raise InterlockError(f"the recipe at point {best['point']} fails its pre-flight ({plan.law}): {problems}")

    def write(tmp: Path) -> None:
        tmp.write_text(text, encoding="utf-8")

    write_atomically(Path(path), write)
    return {
        "file": str(path),
        "point": best["point"],
        "law": plan.law,
        "total_s": plan.total_s,
        "total_dose_kj_g": plan.total_dose_kj_g,
    }


__all__ = ["recipe_text", "write_recipe"]
