"""The one adapter between studies and the physics engine: a point in, a row of results out.

Everything a worker needs travels in a :class:`PointTask` (picklable, for
process pools and Dask), and the row it returns depends only on the task: the
level-(c) phases are drawn from a seed derived from the study's seed and the
point's parameters, never from the order or the worker. Studies call the
reference engine (numpy/scipy, :mod:`millctl.physics`) through
:func:`evaluate_batch` only, so a batch kernel replaces it here in one place.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from pydantic import ValidationError

from millctl.config.loader import format_validation_errors
from millctl.config.models import LimitLaw, MillConfig
from millctl.errors import PhysicsInputError
from millctl.physics.limits import LimitParams, omega_r_max
from millctl.studies.loads import structural_violations
from millctl.studies.metrics import PointSettings, compute_metrics
from millctl.units import rad_s_to_rpm, rpm_to_rad_s

ParamValue = float | int | str

CONFIG_PATHS: dict[str, tuple[str, ...]] = {
    "spring_n_per_m": ("mill", "spring", "stiffness_n_per_m"),
    "eccentricity_mm": ("mill", "cam", "eccentricity_mm"),
    "cam_shape": ("mill", "cam", "shape"),
    "rod_radius_mm": ("mill", "rods", "radius_mm"),
    "rod_length_mm": ("mill", "rods", "length_mm"),
    "rod_material": ("mill", "rods", "material"),
    "n_rods": ("mill", "rods", "count"),
    "vial_radius_mm": ("mill", "vial", "radius_mm"),
    "vial_material": ("mill", "vial", "material"),
    "powder_charge_g": ("mill", "powder", "charge_g"),
    "variant": ("model", "variant"),
}
"""Where each design parameter lives in the mill configuration."""


@dataclass(frozen=True)
class ConstraintSpec:
    """The constraints as plain data (see :class:`millctl.studies.schema.Constraints`)."""

    law: str = "none"
    drives: bool = True
    max_vibration_rpm: float | None = None
    max_spring_force_n: float | None = None
    cam_contact: bool = False
    contact_fatigue: bool = False


@dataclass(frozen=True)
class PointTask:
    """One point of a study: its index, parameters, and everything needed to evaluate it."""

    index: int
    params: dict[str, ParamValue]
    base: dict[str, Any]
    """The base configuration as plain data (``MillConfig.model_dump(mode="json")``)."""
    metrics: tuple[str, ...]
    settings: PointSettings
    constraints: ConstraintSpec
    seed: int
    variant: str | None = None
    fixed_speeds_rpm: dict[str, float] = field(default_factory=dict)


def point_key(params: dict[str, ParamValue]) -> str:
    """A canonical text key of a point's parameters (resume looks finished points up by it)."""
    return json.dumps({k: params[k] for k in sorted(params)}, sort_keys=True, separators=(",", ":"))


def point_seed(study_seed: int, params: dict[str, ParamValue]) -> int:
    """The seed of a point: a function of the study's seed and the point's parameters only."""
    digest = hashlib.sha256(f"{study_seed}|{point_key(params)}".encode()).digest()
    return int.from_bytes(digest[:8], "little")


def point_config(task: PointTask) -> MillConfig:
    """The base configuration with this point's design parameters (raises on a mill that cannot exist)."""
    data = json.loads(json.dumps(task.base))
    for name, value in task.params.items():
        where = CONFIG_PATHS.get(name)
        if where is None:
            continue
        node = data
        for part in where[:-1]:
            node = node.setdefault(part, {})
        node[where[-1]] = value
    if task.variant is not None:
        data.setdefault("model", {})["variant"] = task.variant
    return MillConfig.model_validate(data)


def _speeds_rpm(task: PointTask) -> tuple[float, float]:
    speeds = {**task.fixed_speeds_rpm, **{k: v for k, v in task.params.items() if k in ("rotary_rpm", "vibration_rpm")}}
    return float(speeds["rotary_rpm"]), float(speeds["vibration_rpm"])


def violations(config: MillConfig, rotary_rpm: float, vibration_rpm: float, c: ConstraintSpec) -> list[str]:
    """Every constraint a point breaks, each saying the value and the bound."""
    found = []
    if c.law != "none":
        law = LimitLaw(c.law)
        limit = float(rad_s_to_rpm(omega_r_max(law, LimitParams.from_config(config), rpm_to_rad_s(vibration_rpm))))
        allowed = (1.0 - config.interlock.margin) * limit
        if rotary_rpm > allowed:
            found.append(
                f"ω_r = {rotary_rpm:.1f} rpm > {allowed:.1f} rpm allowed by {law.value} "
                f"at ω_v = {vibration_rpm:.0f} rpm"
            )
    if c.drives:
        drives = config.drives
        if rotary_rpm > drives.rotary.max_speed_rpm:
            found.append(f"ω_r = {rotary_rpm:.1f} rpm > rotary drive maximum {drives.rotary.max_speed_rpm:g} rpm")
        if vibration_rpm > drives.vibration.max_speed_rpm:
            found.append(
                f"ω_v = {vibration_rpm:.1f} rpm > vibration drive maximum {drives.vibration.max_speed_rpm:g} rpm"
            )
    if c.max_vibration_rpm is not None and vibration_rpm > c.max_vibration_rpm:
        found.append(f"ω_v = {vibration_rpm:.1f} rpm > structural limit {c.max_vibration_rpm:g} rpm")
    if c.max_spring_force_n is not None:
        force = config.mill.spring.stiffness_n_per_m * config.mill.cam.eccentricity_m
        if force > c.max_spring_force_n:
            found.append(f"spring force amplitude k·r_d = {force:.3g} N > structural limit {c.max_spring_force_n:g} N")
    if c.cam_contact or c.contact_fatigue:
        found += structural_violations(config, vibration_rpm, c.cam_contact, c.contact_fatigue)
    return found


def evaluate(task: PointTask) -> dict[str, Any]:
    """One point: its parameters, metrics, events, feasibility and the reasons, as one flat row."""
    rotary_rpm, vibration_rpm = _speeds_rpm(task)
    row: dict[str, Any] = {"point": task.index, "key": point_key(task.params), **task.params}
    row |= {"rotary_rpm": rotary_rpm, "vibration_rpm": vibration_rpm}
    try:
        config = point_config(task)
        values, events = compute_metrics(
            config,
            rpm_to_rad_s(rotary_rpm),
            rpm_to_rad_s(vibration_rpm),
            task.metrics,
            task.settings,
            point_seed(task.seed, task.params),
        )
    except ValidationError as exc:
        reason = "; ".join(format_validation_errors("point", exc))
        return row | dict.fromkeys(task.metrics, math.nan) | {"events": 0, "feasible": False, "violations": reason}
    except PhysicsInputError as exc:
        return row | dict.fromkeys(task.metrics, math.nan) | {"events": 0, "feasible": False, "violations": str(exc)}
    broken = violations(config, rotary_rpm, vibration_rpm, task.constraints)
    return row | values | {"events": events, "feasible": not broken, "violations": "; ".join(broken)}


def evaluate_batch(tasks: Sequence[PointTask]) -> list[dict[str, Any]]:
    """Evaluate points in order; the unit a worker runs (the place a batch kernel plugs in)."""
    return [evaluate(t) for t in tasks]


__all__ = [
    "CONFIG_PATHS",
    "ConstraintSpec",
    "PointTask",
    "evaluate",
    "evaluate_batch",
    "point_config",
    "point_key",
    "point_seed",
    "violations",
]
