"""One scene at a time through the compiled event loop, with nothing built per call (the public API's path).

:func:`millctl.physics.methods.first_impact` asks for one scene's first impact at a time. Through the
batch entry point (:func:`.events.first_impacts`) each call built a parameter row, a one-row table, a
result table and seven work arrays and looked up result columns by name: Python wrapping worth more
than the kernel's own work. :class:`SceneCall` keeps, per thread, the last model's parameter row, one
result row and one work buffer, and hands the kernel only the scene's four numbers (ω_r, the cam's
lift speed and phase, θ0); the answer is the same row :func:`.events.first_impacts` returns, bit for bit.

:class:`EventCall` goes further for a caller that asks many events of one model (a design study's unit,
one rod's event): the model, the settings and the work arrays are fixed and checked once, when it is made,
and a call passes only the scene's four floats to one compiled function that leaves the result in a
reused row; no Python object is built per call but the row's view.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from millctl.errors import PhysicsInputError
from millctl.physics.cam import strokes
from millctl.physics.kernels.events import _PREPARED_HEAD, _prepared_event, _scene_event, _scratch_len
from millctl.physics.kernels.layout import OUT, PARAMS, FloatArray, scene_row
from millctl.physics.model import MillModel, Scene

_FOUND = OUT.index("found")


class _Slot:
    """One thread's reused arrays: the current model's parameter row, a result row, a work buffer."""

    __slots__ = ("buf", "lift", "model", "model_row", "out", "rods")

    def __init__(self) -> None:
        self.model: MillModel | None = None
        self.model_row: FloatArray = np.zeros(len(PARAMS))
        self.lift = 1.0
        self.out: FloatArray = np.empty(len(OUT))
        self.rods = 0
        self.buf: FloatArray = np.zeros(len(PARAMS))

    def use(self, scene: Scene) -> None:
        """Take ``scene``'s model: its parameter row, its cam's strokes, a buffer for its rods."""
        m = scene.model
        self.model_row = scene_row(scene)  # the scene's own columns are overwritten per call
        self.lift = float(strokes(m.cam))
        if m.n_rods > self.rods:
            self.rods = m.n_rods
            self.buf = np.zeros(int(_scratch_len(m.n_rods)) + len(PARAMS))
        self.model = m


class SceneCall:
    """A reused call path for one scene's first impact (thread-safe: each thread has its own arrays)."""

    def __init__(self) -> None:
        self._local = threading.local()

    def first_impact(
        self,
        scene: Scene,
        *,
        all_rods: bool = True,
        horizon_s: float = 5.0,
        flight_cap_s: float = math.inf,
        tol_s: float = 0.0,
    ) -> list[float] | None:
        """The result row (:data:`~.layout.OUT` columns) of ``scene``'s first impact, or None if nothing touches.

        ``all_rods``: every rod detaches at its own time (``rods="all"`` of :func:`.events.first_impacts`)
        or only rod 0 (``"one"``); ``horizon_s``, ``flight_cap_s``, ``tol_s`` as there (s).
        """
        slot: _Slot | None = getattr(self._local, "slot", None)
        if slot is None:
            slot = self._local.slot = _Slot()
        if slot.model is not scene.model:
            slot.use(scene)
        out = slot.out
        _scene_event(
            slot.model_row,
            float(scene.omega_r_rad_s),
            slot.lift * scene.omega_v_rad_s,
            float(scene.theta0_rad),
            slot.lift * scene.alpha0_rad,
            all_rods,
            horizon_s,
            flight_cap_s,
            tol_s,
            out,
            slot.buf,
        )
        if out[_FOUND] != 1.0:
            return None
        row: list[float] = out.tolist()
        return row


_HEAD = len(_PREPARED_HEAD)
_OUT_AT = _HEAD + len(PARAMS)


class EventCall:
    """One model's first impacts, a scene at a time as plain floats, on arrays made once (not thread-safe).

    ``rods="one"`` (default): rod 0 detaches within one revolution, the others are held on the wall (one
    rod's event, ``rods="one"`` of :func:`.events.first_impacts`, flights up to ``flight_cap_s`` = 2 s);
    ``"all"``: every rod detaches at its own time (the whole scene, up to ``horizon_s`` = 5 s, as
    ``methods.first_impact(scene, "exact")``). The settings are checked here; a call checks nothing (give
    finite speeds ≥ 0 and finite phases, as :meth:`millctl.physics.batch.SceneBatch.broadcast` requires).
    Use one per thread: the result row is shared by the calls.
    """

    def __init__(
        self,
        model: MillModel,
        *,
        rods: str = "one",
        horizon_s: float | None = None,
        flight_cap_s: float | None = None,
        tol_s: float = 0.0,
    ) -> None:
        if rods == "one":
            horizon = math.inf if horizon_s is None else float(horizon_s)
            cap = 2.0 if flight_cap_s is None else float(flight_cap_s)
        elif rods == "all":
            horizon = 5.0 if horizon_s is None else float(horizon_s)
            cap = math.inf if flight_cap_s is None else float(flight_cap_s)
        else:
            raise PhysicsInputError(f"rods = {rods!r}: choose 'one' or 'all' (millctl.physics.batch)")
        if not (tol_s >= 0.0 and horizon > 0.0 and cap >= 0.0):
            raise PhysicsInputError(
                f"tol_s = {tol_s}, horizon_s = {horizon}, flight_cap_s = {cap}: each must be ≥ 0 (the horizon > 0)"
            )
        self.model = model
        self.rods = rods
        n = model.n_rods
        buf = np.zeros(_OUT_AT + len(OUT) + int(_scratch_len(n)))
        buf[:_HEAD] = (n, 1.0 if rods == "all" else 0.0, horizon, cap, float(tol_s), float(strokes(model.cam)))
        buf[_HEAD:_OUT_AT] = scene_row(Scene(model, 0.0, 0.0))  # the scene's own columns are set per call
        self._buf = buf
        self.row: FloatArray = buf[_OUT_AT : _OUT_AT + len(OUT)]
        """The last call's result row (:data:`~.layout.OUT` columns), overwritten by the next call."""
        self._kernel = _prepared_event

    def __call__(
        self, omega_r_rad_s: float, omega_v_rad_s: float, theta0_rad: float = -0.5 * math.pi, alpha0_rad: float = 0.0
    ) -> FloatArray | None:
        """The first impact of the scene: :attr:`row`, or None if nothing touches (copy the row to keep it).

        ω_r, ω_v of the cam motor in rad/s; θ0, α0 in rad; the row is overwritten by the next call.
        """
        return self.row if self._kernel(self._buf, omega_r_rad_s, omega_v_rad_s, theta0_rad, alpha0_rad) else None


__all__ = ["EventCall", "SceneCall"]
