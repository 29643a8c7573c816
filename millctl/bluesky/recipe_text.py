"""Plans written as recipes: the TOML a plan's trajectory becomes, for the service's pre-flight and runner.

A plan that moves the mill through points is first sent, as this recipe, to ``POST /v1/recipe/check``: the
service plans the whole trajectory against its own envelope (ramps, linear ramps crossing the limit mid-way,
the furnace, the final stop) exactly as ``millctl recipe check`` does, and the plan fails before its first move
when any part is outside. A dose is the recipe runner's to integrate, so a hold to a dose runs as this recipe.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass

from millctl.errors import InvalidInputError


@dataclass(frozen=True)
class Ramp:
    """Move to ``rotary_rpm``/``vibration_rpm`` (rpm), with a furnace target ``furnace_c`` (°C) or None."""

    rotary_rpm: float
    vibration_rpm: float
    furnace_c: float | None = None


@dataclass(frozen=True)
class Hold:
    """Keep the setpoints for ``duration_s`` seconds, or until ``dose_kj_g`` kJ per g of powder (exactly one)."""

    duration_s: float | None = None
    dose_kj_g: float | None = None

    def __post_init__(self) -> None:
        if (self.duration_s is None) == (self.dose_kj_g is None):
            raise InvalidInputError(f"a hold takes exactly one of duration_s or dose_kj_g (got duration_s = "
                                    f"{self.duration_s}, dose_kj_g = {self.dose_kj_g})")


Step = Ramp | Hold


def _value(value: float | str) -> str:
    return json.dumps(value) if isinstance(value, str) else repr(float(value))


def recipe_toml(name: str, steps: Sequence[Step], *, note: str = "") -> str:
    """The recipe of ``steps`` as TOML text (docs/operations.md#recipes); an empty plan is refused."""
    if not steps:
        raise InvalidInputError(f"plan {name!r} has no steps: give at least one point")
    lines = ["[recipe]", f"name = {_value(name)}"]
    if note:
        lines.append(f"operator_note = {_value(note)}")
    for step in steps:
        lines += ["", "[[steps]]"]
        if isinstance(step, Ramp):
            lines += ['kind = "ramp"', f"rotary_rpm = {_value(step.rotary_rpm)}",
                      f"vibration_rpm = {_value(step.vibration_rpm)}"]
            if step.furnace_c is not None:
                lines.append(f"furnace_c = {_value(step.furnace_c)}")
        else:
            lines.append('kind = "hold"')
            if step.duration_s is not None:
                lines.append(f"duration_s = {_value(step.duration_s)}")
            else:
                assert step.dose_kj_g is not None
                lines.append(f"dose_kj_g = {_value(step.dose_kj_g)}")
    return "\n".join(lines) + "\n"


__all__ = ["Hold", "Ramp", "Step", "recipe_toml"]
