"""Run a study: expand its points (grid, list, or optimiser), evaluate the unfinished ones, pick the best.

Grid and list studies take the Cartesian product of every parameter's values,
in the order the file declares them. Optimiser studies run scipy's
``differential_evolution`` with the study's seed and deferred updating, its
population evaluated by the same backend as a grid; every evaluated point is a
row, so an interrupted optimisation replays from the results file without
recomputing (the seeded optimiser asks for the same points again).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from millctl.config.models import CamShape, MillConfig, ModelVariant
from millctl.studies.backends import Backend, SerialBackend, batched
from millctl.studies.engine import ConstraintSpec, ParamValue, PointTask, point_key
from millctl.studies.metrics import DEFAULT_METRICS, METRICS, PointSettings, needs_slip_run
from millctl.studies.schema import CATEGORICAL, INTEGER, Optimiser, Parameter, Study, StudyError
from millctl.studies.store import ResultsStore, fingerprint_of

Progress = Callable[[int, int], None]
"""Called with (points done, points in total) after every batch."""

PENALTY = 1e30
"""What the optimiser minimises at an infeasible point (scipy needs a finite number)."""
HEAP_METRIC = "slip_sim_overlap_share"
HEAP_SHARE = 0.5
"""A finding of ``slip_sim_*`` metrics carries a caveat where more of the slide time than this was spent inside
another rod (:func:`heap_caveat`)."""


@dataclass(frozen=True)
class StudyResult:
    """Every row of a study, and the best feasible one under its objective."""

    rows: list[dict[str, Any]]
    best: dict[str, Any] | None
    computed: int
    """Points evaluated in this run (the rest came from the results file)."""
    reused: int
    metrics: tuple[str, ...]
    objective: dict[str, float]
    findings: list[dict[str, Any]] = field(default_factory=list)
    """The best feasible point for each value of the categorical parameters (e.g. each model variant),
    under the objective and under each ``objective.compare`` metric (:func:`findings`)."""


def metric_names(study: Study, source: str) -> tuple[str, ...]:
    """The study's metrics (default: levels a and b) plus any its objective needs; unknown names are errors."""
    names = list(study.metrics.names or DEFAULT_METRICS)
    names += [n for n in study.objective.terms if n not in names]
    names += [n for n in study.objective.compare if n not in names]
    if needs_slip_run(names) and HEAP_METRIC not in names:
        names.append(HEAP_METRIC)  # it comes with the same run, and says whether the others can be read
    unknown = [n for n in names if n not in METRICS]
    if unknown:
        known = ", ".join(sorted(METRICS))
        raise StudyError(source, [f"{source}: metrics {', '.join(unknown)} unknown (known: {known})"])
    return tuple(names)


def objective_value(row: dict[str, Any], terms: dict[str, float]) -> float:
    """Σ weight·metric at a feasible point; nan where infeasible or a term is not finite."""
    if not row.get("feasible"):
        return math.nan
    total = 0.0
    for name, weight in terms.items():
        value = float(row[name])
        if not math.isfinite(value):
            return math.nan
        total += weight * value
    return total


def grid_points(study: Study) -> list[dict[str, ParamValue]]:
    """Every combination of the parameters' grid or list values, in declared order (last varies fastest)."""
    axes: list[list[ParamValue]] = []
    for name, sweep in study.parameters.items():
        values: list[ParamValue] = list(sweep.grid.values()) if sweep.grid is not None else list(sweep.values or [])
        axes.append([round(float(v)) if name in INTEGER else v for v in values])
    names = [p.value for p in study.parameters]
    return [dict(zip(names, combo, strict=True)) for combo in itertools.product(*axes)]


class StudyRunner:
    """One study against one base configuration, a backend and a results store."""

    def __init__(
        self,
        study: Study,
        base: MillConfig,
        source: str,
        store: ResultsStore | None = None,
        batch_size: int | None = None,
    ) -> None:
        self.study = study
        self.base = base
        self.metrics = metric_names(study, source)
        self.terms = study.objective.terms
        c = study.constraints
        self._constraints = ConstraintSpec(
            str(c.law), c.drives, c.max_vibration_rpm, c.max_spring_force_n, c.cam_contact, c.contact_fatigue
        )
        m = study.metrics
        self._settings = PointSettings(m.cam_phases or 0, m.revolutions, m.cam_phase_rtol, m.slip_phases)
        self._base_data = base.model_dump(mode="json")
        fixed = {
            k: v for k, v in (("rotary_rpm", study.study.rotary_rpm), ("vibration_rpm", study.study.vibration_rpm))
        }
        self._fixed = {k: float(v) for k, v in fixed.items() if v is not None}
        self.fingerprint = fingerprint_of(study.model_dump(mode="json"), self._base_data)
        self.store = store if store is not None else ResultsStore(None, self.fingerprint)
        self._batch_size = batch_size
        self._index: dict[str, int] = {}
        self.computed = 0

    @property
    def batch_cap(self) -> int:
        """The largest batch: arrays of up to 1024 level-(a, b) points; 16 points when one simulates (level c).

        A batch is the unit an interrupt loses (the finished ones are saved), and a simulated point takes
        tens of milliseconds where an array point takes tens of microseconds.
        """
        return 16 if any(METRICS[n].level == "c" for n in self.metrics) else 1024

    def task(self, params: dict[str, ParamValue]) -> PointTask:
        """The task of one point (its number is the order in which the study first asked for it)."""
        key = point_key(params)
        index = self._index.setdefault(key, len(self._index))
        variant = None if self.study.study.variant is None else self.study.study.variant.value
        return PointTask(
            index, params, self._base_data, self.metrics, self._settings, self._constraints,
            self.study.study.seed, variant, self._fixed,
        )  # fmt: skip

    def evaluate(
        self, points: Sequence[dict[str, ParamValue]], backend: Backend, progress: Progress | None = None
    ) -> list[dict[str, Any]]:
        """Rows of the points, computing only those not yet in the store; in the order given."""
        tasks = [self.task(p) for p in points]
        pending = [t for t in tasks if point_key(t.params) not in self.store.rows]
        size = self._batch_size or max(1, min(self.batch_cap, math.ceil(len(pending) / (8 * backend.workers))))
        done = len(tasks) - len(pending)
        if progress is not None:
            progress(done, len(tasks))
        for rows in backend.map(batched(pending, size)):
            self.store.add(rows)
            self.computed += len(rows)
            done += len(rows)
            if progress is not None:
                progress(done, len(tasks))
        return [self.store.rows[point_key(t.params)] for t in tasks]

    def run(self, backend: Backend, progress: Progress | None = None) -> StudyResult:
        """Run the whole study (grid or optimiser) and pick the best feasible point."""
        reused = len(self.store.rows)
        if self.study.is_optimisation:
            self._optimise(backend, progress)
            rows = self.store.ordered()
        else:
            rows = self.evaluate(grid_points(self.study), backend, progress)
        for row in rows:
            row["objective"] = objective_value(row, self.terms)
        scored = [r for r in rows if math.isfinite(r["objective"])]
        best = max(scored, key=lambda r: (r["objective"], -int(r["point"]))) if scored else None
        found = findings(rows, self.study)
        return StudyResult(rows, best, self.computed, reused, self.metrics, self.terms, found)

    def _params_of(self, x: Iterable[float]) -> dict[str, ParamValue]:
        out: dict[str, ParamValue] = {}
        for name, value in zip(self.study.parameters, x, strict=True):
            out[name.value] = round(float(value)) if name in INTEGER else float(value)
        return out

    def _optimise(self, backend: Backend, progress: Progress | None) -> None:
        from scipy.optimize import differential_evolution

        settings = self.study.optimiser or Optimiser()
        bounds = [s.bounds for s in self.study.parameters.values()]

        def energy(row: dict[str, Any]) -> float:
            value = objective_value(row, self.terms)
            return -value if math.isfinite(value) else PENALTY

        def one(x: Any) -> float:
            return energy(self.evaluate([self._params_of(np.atleast_1d(x))], SerialBackend())[0])

        def mapper(_func: Any, population: Iterable[Any]) -> list[float]:
            points = [self._params_of(np.atleast_1d(x)) for x in population]
            return [energy(r) for r in self.evaluate(points, backend, progress)]

        differential_evolution(
            one,
            bounds,
            seed=self.study.study.seed,
            maxiter=settings.max_iterations,
            popsize=settings.population,
            tol=settings.tolerance,
            updating="deferred",
            workers=mapper,
            polish=False,
            init="latinhypercube",
        )


def findings(rows: Sequence[dict[str, Any]], study: Study) -> list[dict[str, Any]]:
    """Best feasible point per combination of the categorical parameters, under each criterion.

    The criteria are the objective and every ``objective.compare`` metric (maximised alone). Each
    finding names its group, its criterion, the point's speeds and parameters, and the value; a
    group with no feasible point under a criterion is a finding with ``point`` None.
    """
    groups = [p.value for p in study.parameters if p in CATEGORICAL]
    numeric = [p.value for p in study.parameters if p not in CATEGORICAL]
    criteria: list[tuple[str, dict[str, float]]] = [("objective", study.objective.terms)]
    criteria += [(name, {name: 1.0}) for name in study.objective.compare]
    keys = sorted({tuple(r[g] for g in groups) for r in rows})
    out = []
    for key in keys:
        members = [r for r in rows if tuple(r[g] for g in groups) == key]
        for label, terms in criteria:
            scored = [(objective_value(r, terms), r) for r in members]
            scored = [(v, r) for v, r in scored if math.isfinite(v)]
            entry: dict[str, Any] = {**dict(zip(groups, key, strict=True)), "criterion": label}
            if not scored:
                out.append(entry | {"point": None, "value": None})
                continue
            value, row = max(scored, key=lambda vr: (vr[0], -int(vr[1]["point"])))
            entry |= {"point": row["point"], **{n: row[n] for n in numeric}, "value": value}
            caveat = heap_caveat(row, terms)
            if caveat:
                entry["caveat"] = caveat
            out.append(entry)
    return out


def heap_caveat(row: dict[str, Any], terms: Iterable[str]) -> str | None:
    """Why a criterion of ``slip_sim_*`` metrics cannot be read at this point, or None.

    Level (c) does not test held rods against each other: with slip they slide through each other to the
    bottom (docs/model.md, "What it does not model"). Above :data:`HEAP_SHARE` of the slide time spent
    inside another rod the figures are the single rods' slide and fall, not a pile's.
    """
    share = row.get(HEAP_METRIC)
    if not needs_slip_run(terms) or share is None or not math.isfinite(float(share)) or float(share) <= HEAP_SHARE:
        return None
    return (
        f"point {row['point']}: {float(share):.0%} of its slide time a rod was inside another "
        f"({HEAP_METRIC} > {HEAP_SHARE}): the slip_sim_* figures describe rods heaped through each other, "
        "not a pile (held rods do not meet in level (c); docs/model.md)"
    )


def pareto_front(rows: Sequence[dict[str, Any]], metrics: Sequence[str]) -> list[dict[str, Any]]:
    """Feasible rows no other feasible row beats in every metric (``-name`` minimises), by first metric."""
    signs = [-1.0 if m.startswith("-") else 1.0 for m in metrics]
    names = [m.lstrip("-") for m in metrics]
    candidates = [r for r in rows if r.get("feasible") and all(math.isfinite(float(r[n])) for n in names)]
    values = np.array([[s * float(r[n]) for s, n in zip(signs, names, strict=True)] for r in candidates])
    front = []
    for i, row in enumerate(candidates):
        others = np.delete(values, i, axis=0)
        dominated = bool(np.any(np.all(others >= values[i], axis=1) & np.any(others > values[i], axis=1)))
        if not dominated:
            front.append(row)
    return sorted(front, key=lambda r: float(r[names[0]]))


def check_parameters(study: Study, base: MillConfig, source: str) -> None:
    """Speeds must be varied or fixed in [study]; materials and cam shapes must be known names."""
    problems = []
    for speed in (Parameter.ROTARY_RPM, Parameter.VIBRATION_RPM):
        fixed = getattr(study.study, speed.value)
        if speed not in study.parameters and fixed is None:
            problems.append(f"{source}: {speed.value}: vary it under [parameters] or fix it in [study]")
    known = {
        Parameter.ROD_MATERIAL: sorted(base.materials),
        Parameter.VIAL_MATERIAL: sorted(base.materials),
        Parameter.CAM_SHAPE: [c.value for c in CamShape],
        Parameter.VARIANT: [v.value for v in ModelVariant],
    }
    for name, names in known.items():
        sweep = study.parameters.get(name)
        for value in (sweep.values or []) if sweep is not None else []:
            if value not in names:
                problems.append(
                    f"{source}: parameters.{name.value}.values: {value!r} unknown (known: {', '.join(names)})"
                )
    if problems:
        raise StudyError(source, problems)


__all__ = [
    "PENALTY",
    "StudyResult",
    "StudyRunner",
    "check_parameters",
    "findings",
    "grid_points",
    "objective_value",
    "pareto_front",
]
