"""The study file (TOML): the base mill, the parameters to vary and how, metrics, constraints, objective.

A study is read and validated in one place; unknown keys are errors, and every
error names the file, the field, the value and the bound (docs/studies.md)::

    [study]
    name = "operating point, Set A"
    config = "../mill.toml"        # base configuration, relative to this file (default: the one in force)
    variant = "corrected"          # physics variant of every point (default: the base config's)
    seed = 1                       # seeds the level-(c) initial phases and the optimiser

    [parameters.rotary_rpm]
    grid = { start = 20, stop = 300, num = 15 }    # or values = [...], or bounds = [lo, hi] (optimiser)

    [metrics]
    names = ["milling_power_w", "dose_rate_j_g_s"]

    [constraints]
    law = "corrected-every-phase"  # the interlock envelope under this law (config margin)
    drives = true
    max_vibration_rpm = 1000.0
    max_spring_force_n = 0.5

    [objective]
    maximize = "dose_rate_j_g_s"   # or minimize = ..., or weights = { metric = weight, ... }

    [optimiser]                    # only when parameters give bounds
    method = "differential-evolution"
    max_iterations = 20
"""

from __future__ import annotations

import enum
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from millctl.config.loader import read_toml, validate_as
from millctl.config.models import LimitLaw, ModelVariant
from millctl.errors import StudyError


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Parameter(enum.StrEnum):
    """What a study may vary: speeds, the mill's design, and the powder charge."""

    ROTARY_RPM = "rotary_rpm"
    VIBRATION_RPM = "vibration_rpm"
    SPRING_N_PER_M = "spring_n_per_m"
    ECCENTRICITY_MM = "eccentricity_mm"
    CAM_SHAPE = "cam_shape"
    ROD_RADIUS_MM = "rod_radius_mm"
    ROD_LENGTH_MM = "rod_length_mm"
    ROD_MATERIAL = "rod_material"
    N_RODS = "n_rods"
    VIAL_RADIUS_MM = "vial_radius_mm"
    VIAL_MATERIAL = "vial_material"
    POWDER_CHARGE_G = "powder_charge_g"
    VARIANT = "variant"


PARAMETER_NAMES: dict[Parameter, tuple[str, str]] = {
    Parameter.ROTARY_RPM: ("ω_r, vial speed", "rpm"),
    Parameter.VIBRATION_RPM: ("ω_v, cam speed", "rpm"),
    Parameter.SPRING_N_PER_M: ("spring stiffness k", "N/m"),
    Parameter.ECCENTRICITY_MM: ("cam eccentricity", "mm"),
    Parameter.CAM_SHAPE: ("cam shape", ""),
    Parameter.ROD_RADIUS_MM: ("rod radius", "mm"),
    Parameter.ROD_LENGTH_MM: ("rod length", "mm"),
    Parameter.ROD_MATERIAL: ("rod material", ""),
    Parameter.N_RODS: ("number of rods", ""),
    Parameter.VIAL_RADIUS_MM: ("vial radius", "mm"),
    Parameter.VIAL_MATERIAL: ("vial material", ""),
    Parameter.POWDER_CHARGE_G: ("powder charge", "g"),
    Parameter.VARIANT: ("model variant", ""),
}
"""Each parameter's name in tables and figures and its unit ("" for names and counts); the metrics' are in
:data:`millctl.studies.metrics.METRICS`, and :func:`millctl.studies.metrics.quantity_label` reads both."""

CATEGORICAL = frozenset({Parameter.CAM_SHAPE, Parameter.ROD_MATERIAL, Parameter.VIAL_MATERIAL, Parameter.VARIANT})
"""Parameters that take names, not numbers: only ``values`` lists them."""
INTEGER = frozenset({Parameter.N_RODS})
"""Parameters rounded to whole numbers (grid points and optimiser proposals)."""


class Grid(_Strict):
    """``num`` evenly spaced values from ``start`` to ``stop``, both included."""

    start: float
    stop: float
    num: Annotated[int, Field(ge=1, le=100_000)]

    def values(self) -> list[float]:
        """The grid's values, in order."""
        return [float(v) for v in np.linspace(self.start, self.stop, self.num)]


class Sweep(_Strict):
    """How one parameter varies: exactly one of a grid, a list of values, or optimiser bounds."""

    grid: Grid | None = None
    values: Annotated[list[float | int | str], Field(min_length=1, max_length=100_000)] | None = None
    bounds: tuple[float, float] | None = None

    @model_validator(mode="after")
    def _exactly_one(self) -> Sweep:
        given = [name for name in ("grid", "values", "bounds") if getattr(self, name) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of grid, values, bounds (got {', '.join(given) or 'none'})")
        if self.bounds is not None and not self.bounds[0] < self.bounds[1]:
            raise ValueError(f"bounds = {list(self.bounds)} must be [low, high] with low < high")
        return self


class Metrics(_Strict):
    """Which metrics to compute (default: every level-(a) and level-(b) metric)."""

    names: Annotated[list[str], Field(min_length=1)] | None = None
    revolutions: Annotated[float, Field(gt=0.0, le=1_000.0)] = 4.0
    """Level (c): simulated time per point, in revolutions of the vial."""
    cam_phases: Annotated[int, Field(ge=1, le=256)] | None = None
    """Level (b): a fixed number of cam phases; default: integrate over the phase to ``cam_phase_rtol``."""
    cam_phase_rtol: Annotated[float, Field(gt=0.0, le=0.5)] = 0.01
    """Level (b): stated error of the cam-phase integral (relative, milling power and detaching share)."""
    slip_phases: Annotated[int, Field(ge=1, le=64)] = 8
    """Level (s): cam phases ridden with slip per point."""


class Constraints(_Strict):
    """Which points are feasible."""

    law: LimitLaw | Literal["none"] = "none"
    """The interlock envelope under this law, with the configured margin; "none" = no envelope."""
    drives: bool = True
    """Both speeds within the drives' maximum speeds."""
    max_vibration_rpm: Annotated[float, Field(gt=0.0)] | None = None
    """Structural limit on the vibration speed (rpm)."""
    max_spring_force_n: Annotated[float, Field(gt=0.0)] | None = None
    """Structural limit on the spring force amplitude k·r_d (N)."""
    cam_contact: bool = False
    """The roller stays on the cam at every cam phase (docs/model.md#structural-loads)."""
    contact_fatigue: bool = False
    """The cam–roller contact pressure stays at or below its endurance limit (infinite life)."""


class Objective(_Strict):
    """What the best point maximises (or minimises): one metric, or a weighted sum of metrics."""

    maximize: str | None = None
    minimize: str | None = None
    weights: dict[str, float] | None = None
    """Maximise Σ weight·metric (a negative weight penalises)."""
    compare: list[str] = []
    """Metrics also maximised, each on its own, for the findings (e.g. the same power with slip)."""

    @model_validator(mode="after")
    def _exactly_one(self) -> Objective:
        given = [name for name in ("maximize", "minimize", "weights") if getattr(self, name) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of maximize, minimize, weights (got {', '.join(given) or 'none'})")
        if self.weights is not None and not self.weights:
            raise ValueError("weights must name at least one metric")
        return self

    @property
    def terms(self) -> dict[str, float]:
        """The objective as {metric: weight}, to be maximised."""
        if self.maximize is not None:
            return {self.maximize: 1.0}
        if self.minimize is not None:
            return {self.minimize: -1.0}
        assert self.weights is not None
        return dict(self.weights)


class Optimiser(_Strict):
    """scipy's optimiser over the bounded parameters (deterministic for a given seed)."""

    method: Literal["differential-evolution"] = "differential-evolution"
    max_iterations: Annotated[int, Field(ge=1, le=10_000)] = 20
    population: Annotated[int, Field(ge=2, le=200)] = 8
    """Population size per parameter (scipy's ``popsize``)."""
    tolerance: Annotated[float, Field(gt=0.0, le=1.0)] = 1e-3


class Header(_Strict):
    """The study's name and base."""

    name: Annotated[str, Field(min_length=1, max_length=200)]
    config: str | None = None
    """Base mill configuration, relative to the study file (default: the configuration in force)."""
    variant: ModelVariant | None = None
    seed: Annotated[int, Field(ge=0, le=2**32 - 1)] = 0
    rotary_rpm: Annotated[float, Field(ge=0.0, le=10_000.0)] | None = None
    """Rotary speed of every point when it is not a parameter (rpm)."""
    vibration_rpm: Annotated[float, Field(ge=0.0, le=10_000.0)] | None = None
    """Vibration (cam motor) speed of every point when it is not a parameter (rpm)."""
    note: str = ""


class Study(_Strict):
    """A whole study file."""

    study: Header
    parameters: Annotated[dict[Parameter, Sweep], Field(min_length=1)]
    metrics: Metrics = Metrics()
    constraints: Constraints = Constraints()
    objective: Objective
    optimiser: Optimiser | None = None

    @model_validator(mode="after")
    def _consistent(self) -> Study:
        bounded = [p for p, s in self.parameters.items() if s.bounds is not None]
        if bounded and len(bounded) != len(self.parameters):
            listed = [p.value for p in self.parameters if p not in bounded]
            raise ValueError(
                f"an optimiser study gives bounds for every parameter; {', '.join(listed)} give a grid or values"
            )
        for p, s in self.parameters.items():
            if p in CATEGORICAL and s.values is None:
                raise ValueError(f"parameters.{p.value} takes names: give values = [...]")
            if p in CATEGORICAL and s.values is not None and not all(isinstance(v, str) for v in s.values):
                raise ValueError(f"parameters.{p.value}.values must be names (strings), got {s.values!r}")
            if p not in CATEGORICAL and s.values is not None and any(isinstance(v, str) for v in s.values):
                raise ValueError(f"parameters.{p.value}.values must be numbers, got {s.values!r}")
        if self.optimiser is not None and not bounded:
            raise ValueError("[optimiser] needs parameters with bounds = [low, high]")
        return self

    @property
    def is_optimisation(self) -> bool:
        """True when the parameters give bounds (an optimiser study), False for a grid or list sweep."""
        return all(s.bounds is not None for s in self.parameters.values())


def load_study(path: str | Path) -> Study:
    """Read and validate a study file; errors name the file, the field, the value and the bound."""
    path = Path(path)
    data, _ = read_toml(path, StudyError)
    return validate_as(Study, data, str(path), StudyError)


__all__ = [
    "CATEGORICAL",
    "INTEGER",
    "PARAMETER_NAMES",
    "Constraints",
    "Grid",
    "Header",
    "Metrics",
    "Objective",
    "Optimiser",
    "Parameter",
    "Study",
    "StudyError",
    "Sweep",
    "load_study",
]
