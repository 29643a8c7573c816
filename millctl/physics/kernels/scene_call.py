"""One scene at a time through the compiled event loop, with nothing built per call (the public API's path).

:func:`millctl.physics.methods.first_impact` asks for one scene's first impact at a time. Through the
batch entry point (:func:`.events.first_impacts`) each call built a parameter row, a one-row table, a
result table and seven work arrays and looked up result columns by name: Python wrapping worth more
than the kernel's own work. :class:`SceneCall` keeps, per thread, the last model's parameter row, one
result row and one work buffer, and hands the kernel only the scene's four numbers (ω_r, the cam's
lift speed and phase, θ0); the answer is the same row :func:`.events.first_impacts` returns, bit for bit.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from millctl.physics.cam import strokes
from millctl.physics.kernels.events import _scene_event, _scratch_len
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


__all__ = ["SceneCall"]
