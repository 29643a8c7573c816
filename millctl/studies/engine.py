"""The one adapter between studies and the physics engine: arrays of points in, arrays of results out.

**The array interface (issue 40)** — what a worker runs, and what a metric must be::

    evaluate_arrays(points: dict[str, np.ndarray], base: MillConfig, metrics: Sequence[str],
                    settings: PointSettings | None = None, *, constraints: ConstraintSpec | None = None,
                    seed: int = 0, variant: str | None = None) -> dict[str, np.ndarray]

* ``points``: one 1-D array of length P per parameter: ``rotary_rpm`` and ``vibration_rpm``
  (float, rpm; required), and any design parameter of :data:`CONFIG_PATHS` (float, int or str).
* ``base``: the validated base configuration. Points that share their design parameters form
  one group: one :class:`~millctl.config.MillConfig` and one :class:`~millctl.physics.model.MillModel`
  per group, validated once; the speeds of a group are arrays from there on (no object per point).
* returns one (P,) array per metric (float64, nan where undefined or at an impossible mill), and
  ``events`` (int64: kernel events spent), ``feasible`` (bool) and ``violations`` (str, "; "-joined,
  empty when feasible).
* **A metric is a vectorised function of arrays**: ``fn(points: PointArrays) -> np.ndarray`` of
  shape (P,), registered with ``@array_metric("name_unit")`` from :mod:`millctl.studies.arrays`
  (the name also listed in :data:`millctl.studies.metrics.METRICS`). It reads the speeds
  (``points.omega_r_rad_s``, ``points.omega_v_rad_s``, rad/s), the group's ``points.model`` and
  ``points.config``, and the shared, cached levels: ``points.structure()`` (level a: the
  structural loads), ``points.telemetry()`` (level b at K fixed cam phases: (P, K) arrays, one
  compiled call) and ``points.summary()`` (the per-revolution summary as arrays, at the K phases or,
  with ``cam_phases`` 0, integrated over the phase to ``cam_phase_rtol``). Every level-(a, b) metric
  has an array form; one without (the slip ride, level s; the simulation, level c) is evaluated point
  by point through :func:`~millctl.studies.metrics.compute_metrics` (correct, ~100× slower).

:func:`evaluate_batch` (what the backends map over batches of :class:`PointTask`) groups its tasks
and calls :func:`evaluate_arrays`; :func:`evaluate` is one point through the same path. A point's row
depends only on its task: the level-(c) phases are drawn from a seed derived from the study's seed and
the point's parameters, never from the order or the worker.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import ValidationError

from millctl.config.loader import format_validation_errors
from millctl.config.models import LimitLaw, MillConfig
from millctl.errors import InvalidInputError, PhysicsInputError
from millctl.physics.limits import LimitParams, omega_r_max
from millctl.physics.model import MillModel
from millctl.studies.arrays import ARRAY_METRICS, FloatArray, PointArrays
from millctl.studies.loads import structural_violation_texts, structural_violations
from millctl.studies.metrics import METRICS, PointSettings, compute_metrics
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


def _group_config(base: dict[str, Any], params: dict[str, ParamValue], variant: str | None) -> MillConfig:
    """The base configuration with one group's design parameters (raises on a mill that cannot exist)."""
    data = json.loads(json.dumps(base))
    for name, value in params.items():
        where = CONFIG_PATHS.get(name)
        if where is None:
            continue
        node = data
        for part in where[:-1]:
            node = node.setdefault(part, {})
        node[where[-1]] = value
    if variant is not None:
        data.setdefault("model", {})["variant"] = variant
    return MillConfig.model_validate(data)


def _violations_arrays(
    points: PointArrays, rotary_rpm: FloatArray, vibration_rpm: FloatArray, c: ConstraintSpec
) -> NDArray[np.object_]:
    """:func:`violations` of every point of a group ("" where none), formed only where a bound is broken.

    Texts and lists are made for the broken points alone: a map of 10⁴ points otherwise allocates 10⁴ lists, enough
    to trigger a full garbage collection over numba's object graph (~70 ms, more than the level-(b) kernel's work).
    """
    config = points.config
    found: dict[int, list[str]] = {}
    # the texts format Python floats: a numpy scalar's format costs ~10× more, and a map may break a bound at
    # thousands of points
    w_r, w_v = rotary_rpm.tolist(), vibration_rpm.tolist()

    def add(broken: NDArray[np.bool_], text: Callable[[int], str]) -> None:
        for i in np.flatnonzero(broken).tolist():
            found.setdefault(i, []).append(text(i))

    if c.law != "none":
        law = LimitLaw(c.law)
        limit = np.asarray(rad_s_to_rpm(omega_r_max(law, points.limit_params, rpm_to_rad_s(vibration_rpm))))
        allowed_rpm = (1.0 - config.interlock.margin) * limit
        allowed = allowed_rpm.tolist()
        add(rotary_rpm > allowed_rpm, lambda i: (
            f"ω_r = {w_r[i]:.1f} rpm > {allowed[i]:.1f} rpm allowed by {law.value} at ω_v = {w_v[i]:.0f} rpm"
        ))  # fmt: skip
    if c.drives:
        rotary, vibration = config.drives.rotary.max_speed_rpm, config.drives.vibration.max_speed_rpm
        add(rotary_rpm > rotary, lambda i: f"ω_r = {w_r[i]:.1f} rpm > rotary drive maximum {rotary:g} rpm")
        add(vibration_rpm > vibration, lambda i: (
            f"ω_v = {w_v[i]:.1f} rpm > vibration drive maximum {vibration:g} rpm"
        ))  # fmt: skip
    if c.max_vibration_rpm is not None:
        bound = c.max_vibration_rpm
        add(vibration_rpm > bound, lambda i: f"ω_v = {w_v[i]:.1f} rpm > structural limit {bound:g} rpm")
    if c.max_spring_force_n is not None:
        force = config.mill.spring.stiffness_n_per_m * config.mill.cam.eccentricity_m
        if force > c.max_spring_force_n:
            text = f"spring force amplitude k·r_d = {force:.3g} N > structural limit {c.max_spring_force_n:g} N"
            add(np.ones(points.size, dtype=bool), lambda _i: text)
    if c.cam_contact or c.contact_fatigue:
        structural = structural_violation_texts(config, vibration_rpm, c.cam_contact, c.contact_fatigue)
        for i, texts in structural.items():
            found.setdefault(i, []).extend(texts)
    reasons = np.full(points.size, "", dtype=object)
    for i, texts in found.items():
        reasons[i] = "; ".join(texts)
    return reasons


def _group_metrics(
    points: PointArrays, names: Sequence[str], settings: PointSettings, seeds: Callable[[int], int]
) -> tuple[dict[str, FloatArray], NDArray[np.int64], dict[int, str]]:
    """The named metrics of one group (array forms; the rest point by point), events spent, points that failed.

    A point fails where its point-by-point metrics raise :class:`PhysicsInputError` (index → the message).
    """
    events = np.zeros(points.size, dtype=np.int64)
    arrays = [n for n in names if n in ARRAY_METRICS]
    values = {n: np.asarray(ARRAY_METRICS[n](points), dtype=float) for n in arrays}
    array_phases = np.zeros(points.size, dtype=np.int64)
    if any(METRICS[n].level == "b" for n in arrays):  # the point path counts level (b) as the cam phases it took
        array_phases = points.summary()["cam_phases_used"].astype(np.int64)
        events += array_phases
    rest = tuple(n for n in names if n not in arrays)
    failed: dict[int, str] = {}
    if rest:
        extra = np.full((points.size, len(rest)), math.nan)
        both_b = "b" in {METRICS[n].level for n in rest} and array_phases.any()
        for i in range(points.size):
            try:
                row, spent = compute_metrics(
                    points.config, float(points.omega_r_rad_s[i]), float(points.omega_v_rad_s[i]), rest, settings,
                    seeds(i),
                )  # fmt: skip
            except PhysicsInputError as exc:  # e.g. a slip ride that chatters: this point fails, the rest go on
                failed[i] = str(exc)
                continue
            extra[i] = [row[n] for n in rest]
            events[i] += spent - (array_phases[i] if both_b else 0)
        values |= {n: extra[:, k] for k, n in enumerate(rest)}
    return values, events, failed


def evaluate_arrays(
    points: dict[str, NDArray[Any]],
    base: MillConfig,
    metrics: Sequence[str],
    settings: PointSettings | None = None,
    *,
    constraints: ConstraintSpec | None = None,
    seed: int = 0,
    variant: str | None = None,
    seeds: Sequence[int] | None = None,
) -> dict[str, NDArray[Any]]:
    """Metrics, events, feasibility and reasons of P points at once (the interface in the module docstring).

    ``settings`` default :class:`PointSettings` (); ``constraints`` default: none but the drives';
    ``seeds``: one level-(c) seed per point (default :func:`point_seed` of the point's columns).
    """
    settings = PointSettings() if settings is None else settings
    constraints = ConstraintSpec() if constraints is None else constraints
    if "rotary_rpm" not in points or "vibration_rpm" not in points:
        raise InvalidInputError(f"points need rotary_rpm and vibration_rpm arrays, got {', '.join(points) or 'none'}")
    columns = {k: np.asarray(v).reshape(-1) for k, v in points.items()}
    size = columns["rotary_rpm"].size
    uneven = {k: v.size for k, v in columns.items() if v.size != size}
    if uneven:
        raise InvalidInputError(f"points: every array needs length {size} (rotary_rpm's), got {uneven}")
    rotary = np.abs(columns["rotary_rpm"].astype(float))
    vibration = np.abs(columns["vibration_rpm"].astype(float))
    design = [k for k in columns if k in CONFIG_PATHS]
    out: dict[str, NDArray[Any]] = {n: np.full(size, math.nan) for n in metrics}
    out |= {"events": np.zeros(size, dtype=np.int64), "feasible": np.zeros(size, dtype=bool)}
    out["violations"] = np.full(size, "", dtype=object)
    groups: dict[tuple[Any, ...], Any] = {}
    if not design:  # one mill: every point in one group
        groups[()] = np.arange(size, dtype=np.int64)
    for i, key in enumerate(zip(*(columns[k].tolist() for k in design), strict=True)):
        groups.setdefault(key, []).append(i)
    base_data = base.model_dump(mode="json")
    for key, members in groups.items():
        where = np.asarray(members, dtype=np.int64)
        params = dict(zip(design, key, strict=True))
        try:
            config = _group_config(base_data, params, variant)
            model = MillModel.from_config(config)
        except ValidationError as exc:
            out["violations"][where] = "; ".join(format_validation_errors("point", exc))
            continue
        except PhysicsInputError as exc:
            out["violations"][where] = str(exc)
            continue
        group = PointArrays(
            config, model, rpm_to_rad_s(rotary[where]), rpm_to_rad_s(vibration[where]),
            settings.cam_phases, settings.revolutions, cam_phase_rtol=settings.cam_phase_rtol,
        )  # fmt: skip

        def seed_of(i: int, where: NDArray[np.int64] = where) -> int:
            j = int(where[i])
            if seeds is not None:
                return int(seeds[j])
            return point_seed(seed, {k: _plain(v[j]) for k, v in columns.items()})

        values, events, failed = _group_metrics(group, metrics, settings, seed_of)
        for name, array in values.items():
            out[name][where] = array
        out["events"][where] = events
        reasons = _violations_arrays(group, rotary[where], vibration[where], constraints)
        out["violations"][where] = reasons
        out["feasible"][where] = reasons == ""
        for i, message in failed.items():  # as a mill that cannot exist: no metric, no events, the reason
            j = int(where[i])
            for name in metrics:
                out[name][j] = math.nan
            out["events"][j], out["feasible"][j], out["violations"][j] = 0, False, message
    return out


def _plain(value: Any) -> ParamValue:
    """A numpy scalar as the Python value a study file gives (so that keys and seeds match)."""
    item = value.item() if hasattr(value, "item") else value
    result: ParamValue = item
    return result


def _batch_columns(tasks: Sequence[PointTask]) -> dict[str, NDArray[Any]]:
    names = list(tasks[0].fixed_speeds_rpm) + list(tasks[0].params)
    columns: dict[str, NDArray[Any]] = {}
    for name in dict.fromkeys(names):
        values = [t.params.get(name, t.fixed_speeds_rpm.get(name)) for t in tasks]
        columns[name] = np.asarray(values, dtype=object if isinstance(values[0], str) else None)
    return columns


def evaluate_batch(tasks: Sequence[PointTask]) -> list[dict[str, Any]]:
    """Evaluate points, in order, through :func:`evaluate_arrays` (the unit a worker runs)."""
    rows: list[dict[str, Any]] = []
    start = 0
    while start < len(tasks):
        first = tasks[start]
        same = (first.base, first.metrics, first.settings, first.constraints, first.seed, first.variant)
        end = start + 1
        while end < len(tasks) and (
            tasks[end].base is first.base or tasks[end].base == first.base
        ) and (tasks[end].metrics, tasks[end].settings, tasks[end].constraints, tasks[end].seed,
               tasks[end].variant, set(tasks[end].params)) == (*same[1:], set(first.params)):  # fmt: skip
            end += 1
        rows += _rows(tasks[start:end])
        start = end
    return rows


def _rows(tasks: Sequence[PointTask]) -> list[dict[str, Any]]:
    first = tasks[0]
    simulated = any(METRICS[n].level == "c" for n in first.metrics)
    seeds = [point_seed(t.seed, t.params) for t in tasks] if simulated else None
    result = evaluate_arrays(
        _batch_columns(tasks), MillConfig.model_validate(first.base), first.metrics, first.settings,
        constraints=first.constraints, seed=first.seed, variant=first.variant, seeds=seeds,
    )  # fmt: skip
    lists = {n: result[n].tolist() for n in first.metrics}
    events, feasible, reasons = result["events"].tolist(), result["feasible"].tolist(), result["violations"].tolist()
    rows = []
    for i, task in enumerate(tasks):
        rotary_rpm, vibration_rpm = _speeds_rpm(task)
        row: dict[str, Any] = {"point": task.index, "key": point_key(task.params), **task.params}
        row |= {"rotary_rpm": rotary_rpm, "vibration_rpm": vibration_rpm}
        row |= {n: lists[n][i] for n in first.metrics}
        rows.append(row | {"events": events[i], "feasible": feasible[i], "violations": reasons[i]})
    return rows


def evaluate(task: PointTask) -> dict[str, Any]:
    """One point: its parameters, metrics, events, feasibility and the reasons, as one flat row."""
    return evaluate_batch([task])[0]


__all__ = [
    "CONFIG_PATHS",
    "ConstraintSpec",
    "PointArrays",
    "PointTask",
    "evaluate",
    "evaluate_arrays",
    "evaluate_batch",
    "point_config",
    "point_key",
    "point_seed",
    "violations",
]
