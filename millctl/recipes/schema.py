"""The recipe format (TOML): metadata and steps, validated when read.

A recipe is a sequence of steps, each a table in ``[[steps]]`` with a
``kind``:

* ``ramp`` — move to setpoints (``rotary_rpm``, ``vibration_rpm``, optional
  ``furnace_c``) at given rates; ``path = "sequenced"`` (default) lets the
  planner order the two drives so every instant stays inside the envelope,
  ``path = "linear"`` moves both together and is refused where the straight
  line leaves the envelope;
* ``hold`` — keep the setpoints for a duration, or until a specific energy
  dose (``dose_kj_g``, kJ per g of powder: "mill until D kJ/g");
* ``wait_furnace`` — wait until the furnace is within a band of its setpoint;
* ``pause`` — wait for the operator to resume.

Durations take one of ``duration_s``, ``duration_min`` or ``duration_h``; a
hold may give ``dose_kj_g`` instead. The powder charge of the dose is the
recipe's ``powder_charge_g``, else the configuration's ``mill.powder.charge_g``.
Unknown keys are errors (see docs/operations.md#recipes).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from millctl.config.loader import parse_toml, read_toml, validate_as
from millctl.errors import RecipeError


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Tolerances(_Strict):
    """Per-step tolerances on measured values, checked while the step runs."""

    speed_rpm: Annotated[float, Field(gt=0.0, le=100.0)] = 5.0
    furnace_c: Annotated[float, Field(gt=0.0, le=200.0)] = 15.0


class _Timed(_Strict):
    duration_s: Annotated[float, Field(gt=0.0, le=7 * 86_400.0)] | None = None
    duration_min: Annotated[float, Field(gt=0.0, le=7 * 1_440.0)] | None = None
    duration_h: Annotated[float, Field(gt=0.0, le=7 * 24.0)] | None = None
    dose_kj_g: Annotated[float, Field(gt=0.0, le=1e6)] | None = None
    """Mill until this specific energy dose (kJ per g of powder) instead of for a duration."""

    @model_validator(mode="after")
    def _one_duration(self) -> _Timed:
        given = [v for v in (self.duration_s, self.duration_min, self.duration_h, self.dose_kj_g) if v is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of duration_s, duration_min, duration_h, dose_kj_g (got {len(given)})")
        return self

    @property
    def seconds(self) -> float | None:
        """The duration in seconds; None when the step ends at a dose (its time comes from the plan)."""
        if self.duration_s is not None:
            return self.duration_s
        if self.duration_min is not None:
            return self.duration_min * 60.0
        if self.duration_h is not None:
            return self.duration_h * 3_600.0
        return None


class RampStep(_Strict):
    """Move to new setpoints at given rates."""

    kind: Literal["ramp"]
    rotary_rpm: Annotated[float, Field(ge=0.0, le=10_000.0)]
    vibration_rpm: Annotated[float, Field(ge=0.0, le=10_000.0)]
    furnace_c: Annotated[float, Field(ge=-50.0, le=1_700.0)] | None = None
    rotary_rate_rpm_s: Annotated[float, Field(gt=0.0, le=10_000.0)] | None = None
    vibration_rate_rpm_s: Annotated[float, Field(gt=0.0, le=10_000.0)] | None = None
    heating_rate_c_per_min: Annotated[float, Field(gt=0.0, le=1_000.0)] | None = None
    path: Literal["sequenced", "linear"] = "sequenced"
    tolerances: Tolerances | None = None
    note: str = ""

    @model_validator(mode="after")
    def _rate_needs_target(self) -> RampStep:
        """A heating rate with no furnace target is refused, not ignored: a step is checked whole (SAFETY 20)."""
        if self.heating_rate_c_per_min is not None and self.furnace_c is None:
            raise ValueError(
                f"heating_rate_c_per_min = {self.heating_rate_c_per_min} given without furnace_c: there is nothing "
                "to heat to, and the rate would be ignored; give furnace_c with it, or leave the rate out "
                "(a default rate for every step goes in [defaults])"
            )
        return self


class HoldStep(_Timed):
    """Keep the current setpoints for a duration, or until a specific energy dose."""

    kind: Literal["hold"]
    tolerances: Tolerances | None = None
    note: str = ""


class WaitFurnaceStep(_Strict):
    """Wait until the measured furnace temperature is within a band of its setpoint."""

    kind: Literal["wait_furnace"]
    band_c: Annotated[float, Field(gt=0.0, le=100.0)] = 5.0
    timeout_min: Annotated[float, Field(gt=0.0, le=24 * 60.0)] = 60.0
    note: str = ""


class PauseStep(_Strict):
    """Stop the clock until the operator resumes (the mill keeps its setpoints)."""

    kind: Literal["pause"]
    message: str = "paused by the recipe"


Step = Annotated[RampStep | HoldStep | WaitFurnaceStep | PauseStep, Field(discriminator="kind")]


class Metadata(_Strict):
    """Who and what the recipe is for."""

    name: Annotated[str, Field(min_length=1, max_length=200)]
    material_system: str = ""
    operator_note: str = ""
    powder_charge_g: Annotated[float, Field(gt=0.0, le=10_000.0)] | None = None
    """Powder in the vial (g), for dose steps; default: the configuration's ``mill.powder.charge_g``."""


class Defaults(_Strict):
    """Rates used by ramp steps that do not give their own."""

    rotary_rate_rpm_s: Annotated[float, Field(gt=0.0, le=10_000.0)] | None = None
    vibration_rate_rpm_s: Annotated[float, Field(gt=0.0, le=10_000.0)] | None = None
    heating_rate_c_per_min: Annotated[float, Field(gt=0.0, le=1_000.0)] | None = None
    tolerances: Tolerances = Tolerances()


class Recipe(_Strict):
    """A whole milling recipe."""

    recipe: Metadata
    defaults: Defaults = Defaults()
    steps: Annotated[list[Step], Field(min_length=1, max_length=10_000)]


class LoadedRecipe(_Strict):
    """A validated recipe with where it came from and the hash of its bytes."""

    recipe: Recipe
    source: str
    sha256: str


def parse_recipe(text: str, source: str) -> LoadedRecipe:
    """Validate a recipe given as TOML text (as sent to the service); errors name ``source`` like a file."""
    data = parse_toml(text, source, RecipeError)
    recipe = validate_as(Recipe, data, source, RecipeError)
    return LoadedRecipe(recipe=recipe, source=source, sha256=hashlib.sha256(text.encode()).hexdigest())


def load_recipe(path: str | Path) -> LoadedRecipe:
    """Read and validate a recipe file; errors name the file, the step field, the value and the bound."""
    path = Path(path)
    data, raw = read_toml(path, RecipeError)
    recipe = validate_as(Recipe, data, str(path), RecipeError)
    return LoadedRecipe(recipe=recipe, source=str(path), sha256=hashlib.sha256(raw).hexdigest())


__all__ = [
    "Defaults",
    "HoldStep",
    "LoadedRecipe",
    "Metadata",
    "PauseStep",
    "RampStep",
    "Recipe",
    "Step",
    "Tolerances",
    "WaitFurnaceStep",
    "load_recipe",
    "parse_recipe",
]
