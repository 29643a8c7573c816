"""Many scenes at once: the batch entry point for design studies and sweeps (compiled, one core).

::

    from millctl.physics.batch import SceneBatch, first_impacts

    batch = SceneBatch.broadcast(model, omega_r_rad_s=w_r, omega_v_rad_s=w_v, theta0_rad=th, alpha0_rad=al)
    result = first_impacts(batch, rods="one")          # structured array, BATCH_DTYPE, one row per scene
    result["energy_j"][result["found"]].mean()

Every argument of :meth:`SceneBatch.broadcast` is a scalar or an array; they are
broadcast against each other (numpy rules), so a grid is ``w_r[:, None]`` and
``w_v[None, :]``. ``eccentricity_m`` and ``spring_n_per_m`` may vary per scene too;
everything else comes from ``model``, its cam shape included: ω_v and α0 are the cam
motor's, and the kernels run on the cam's lift (h·ω_v, h·α0, :mod:`.cam`); a result's
``alpha_d_rad`` is the lift's phase.

``rods="one"``: rod 0 starts pinned at θ0 with cam phase α0, detaches within one
revolution, flies, and its first contact with the wall or one of the n − 1 rods
held on the wall is returned (the node telemetry's sample, one "event").
``rods="all"``: every rod detaches at its own time; the scene's first impact (the
same question as ``methods.first_impact(scene, "exact")``). The numpy/scipy
engine (:mod:`.simulate`) is the reference the kernels are tested against.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from millctl.errors import PhysicsInputError
from millctl.physics import kernels
from millctl.physics.cam import strokes
from millctl.physics.kernels.records import records_into
from millctl.physics.model import MillModel, Scene

FloatArray = NDArray[np.float64]

BATCH_DTYPE = np.dtype(
    [
        ("found", "?"),
        ("time_s", "f8"),
        ("rod", "i4"),
        ("partner", "i4"),  # −1 = wall
        ("x_m", "f8"),  # contact point, lab frame
        ("y_m", "f8"),
        ("normal_velocity_m_s", "f8"),
        ("tangential_velocity_m_s", "f8"),
        ("speed_abs_m_s", "f8"),
        ("energy_j", "f8"),
        ("backed", "?"),  # partner is the wall or a rod held by it (m_eff = m)
        ("depart_time_s", "f8"),  # when the impacting rod left the wall
        ("flight_time_s", "f8"),
        ("theta_d_rad", "f8"),
        ("alpha_d_rad", "f8"),
        ("first_detach_time_s", "f8"),  # nan: no rod left the wall
        ("zero_length_flights", "i4"),
    ]
)
"""One row per scene; the fields of a scene with no impact are nan (found False)."""


@dataclass(frozen=True)
class SceneBatch:
    """Scenes as rows of parameters (columns :data:`~millctl.physics.kernels.PARAMS`)."""

    rows: FloatArray

    def __len__(self) -> int:
        return int(self.rows.shape[0])

    @classmethod
    def from_scenes(cls, scenes: list[Scene]) -> SceneBatch:
        """One row per scene."""
        return cls(kernels.scene_rows(scenes))

    @classmethod
    def broadcast(
        cls,
        model: MillModel,
        *,
        omega_r_rad_s: ArrayLike,
        omega_v_rad_s: ArrayLike,
        theta0_rad: ArrayLike = -0.5 * math.pi,
        alpha0_rad: ArrayLike = 0.0,
        eccentricity_m: ArrayLike | None = None,
        spring_n_per_m: ArrayLike | None = None,
    ) -> SceneBatch:
        """Scenes of ``model`` at every combination the broadcast arrays describe (flattened, C order)."""
        r_d = model.eccentricity_m if eccentricity_m is None else eccentricity_m
        k = model.spring_n_per_m if spring_n_per_m is None else spring_n_per_m
        arrays = np.broadcast_arrays(
            *(np.asarray(a, dtype=float) for a in (omega_r_rad_s, omega_v_rad_s, theta0_rad, alpha0_rad, r_d, k))
        )
        w_r, w_v, th, al, rd, kk = (a.ravel() for a in arrays)
        for name, values in (("omega_r_rad_s", w_r), ("omega_v_rad_s", w_v), ("eccentricity_m", rd)):
            bad = ~(np.isfinite(values) & (values >= 0.0))
            if bad.any():
                first = int(np.flatnonzero(bad)[0])
                raise PhysicsInputError(f"{name}[{first}] = {float(values[first])} must be finite and ≥ 0")
        for name, values in (("theta0_rad", th), ("alpha0_rad", al), ("spring_n_per_m", kk)):
            bad = ~np.isfinite(values)
            if bad.any():
                first = int(np.flatnonzero(bad)[0])
                raise PhysicsInputError(f"{name}[{first}] = {float(values[first])} must be finite")
        rows = np.tile(kernels.scene_row(Scene(model, 0.0, 0.0)), (w_r.size, 1))
        lift = strokes(model.cam)  # the kernels run on the cam's lift: h·ω_v, h·α0 (millctl.physics.cam)
        columns = {
            "omega_r_rad_s": w_r,
            "omega_v_rad_s": lift * w_v,
            "theta0_rad": th,
            "alpha0_rad": lift * al,
            "eccentricity_m": rd,
            "spring_per_mass_s2": kk / model.rod_mass_kg,
        }
        for name, values in columns.items():
            rows[:, kernels.PARAMS.index(name)] = values
        return cls(rows)


def first_impacts(
    batch: SceneBatch,
    *,
    rods: str = "one",
    tol_s: float = 0.0,
    horizon_s: float | None = None,
    flight_cap_s: float | None = None,
) -> NDArray[np.void]:
    """The first impact of every scene of ``batch`` (structured array of :data:`BATCH_DTYPE`).

    ``rods`` ``"one"`` (default; detachment within one revolution, flights up to
    ``flight_cap_s`` = 2 s) or ``"all"`` (every rod; up to ``horizon_s`` = 5 s).
    ``tol_s``: the root finder's time tolerance (s; 0 ≈ 4 ulp).
    """
    if rods == "one":
        horizon, cap = (math.inf if horizon_s is None else horizon_s), (2.0 if flight_cap_s is None else flight_cap_s)
    elif rods == "all":
        horizon, cap = (5.0 if horizon_s is None else horizon_s), (math.inf if flight_cap_s is None else flight_cap_s)
    else:
        raise PhysicsInputError(f"rods = {rods!r}: choose 'one' or 'all'")
    if not (tol_s >= 0.0 and horizon > 0.0 and cap >= 0.0):
        raise PhysicsInputError(
            f"tol_s = {tol_s}, horizon_s = {horizon}, flight_cap_s = {cap}: each must be ≥ 0 (the horizon > 0)"
        )
    raw = kernels.first_impacts(batch.rows, rods=rods, horizon_s=horizon, flight_cap_s=cap, tol_s=tol_s)
    return as_records(raw)


def as_records(raw: FloatArray) -> NDArray[np.void]:
    """Kernel result rows (:data:`~millctl.physics.kernels.OUT`) as a structured array of :data:`BATCH_DTYPE`.

    Rod indices and counts as int32 (−1 where there is none), flags as bool, ``flight_time_s`` = impact − departure
    time; one compiled pass (:func:`~millctl.physics.kernels.records.records_into`).
    """
    table = np.ascontiguousarray(raw, dtype=np.float64)
    if table.ndim != 2 or table.shape[1] != len(kernels.OUT):
        raise ValueError(f"raw must have shape (scenes, {len(kernels.OUT)}) (kernels.OUT columns), got {table.shape}")
    out = np.empty(table.shape[0], dtype=BATCH_DTYPE)
    records_into(table, out)
    return out


__all__ = ["BATCH_DTYPE", "SceneBatch", "as_records", "first_impacts"]
