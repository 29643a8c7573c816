"""The node's periodic frames: when each is due, and the physics telemetry cache.

Periods come from the DBC (``Codec.cycle_time_s``): NodeStatus 20 Hz,
DriveTelemetry 50 Hz, FurnaceTelemetry and PhysicsTelemetry 10 Hz.
PhysicsTelemetry is the level-(b) summary of
:func:`millctl.physics.telemetry.revolution_summary` at the measured speeds,
recomputed whenever the frame is due and a speed moved by more than
``PHYSICS_RECOMPUTE_RPM`` since the last one. With the compiled kernels a
summary costs about 0.1 ms (under 1 ms at p99.9 over the operating range), so by
default it runs inside the tick and none is ever skipped (fixed work, measured
by ``python -m bench``, docs/benchmarks.md); a worker thread remains an option.
"""

from __future__ import annotations

import logging
import math
from typing import Literal

from firmware_sim.physics_worker import ThreadWorker
from millctl.config.models import MillConfig
from millctl.physics.model import MillModel
from millctl.physics.telemetry import RevolutionSummary, revolution_summary
from millctl.protocol import (
    Codec,
    DriveTelemetry,
    FurnaceTelemetry,
    MillMessage,
    NodeStatus,
    PhysicsTelemetry,
)
from millctl.protocol.errors import ProtocolError
from millctl.units import rpm_to_rad_s

log = logging.getLogger(__name__)

PERIODIC: tuple[type[MillMessage], ...] = (NodeStatus, DriveTelemetry, FurnaceTelemetry, PhysicsTelemetry)
"""The node's periodic messages, in the order they are sent when due together."""
PHYSICS_RECOMPUTE_RPM = 0.5
"""Recompute the physics summary when either speed moved by more than this (rpm)."""


class Schedule:
    """When each periodic frame is next due (s, node clock); all are due at the first tick."""

    def __init__(self, codec: Codec) -> None:
        self.period_s: dict[type[MillMessage], float] = {}
        for kind in PERIODIC:
            period = codec.cycle_time_s(kind)
            if period is None:
                raise ProtocolError(f"{kind.__name__} has no cycle time in {codec.path}; the node cannot schedule it")
            self.period_s[kind] = period
        self._next_s: dict[type[MillMessage], float | None] = dict.fromkeys(PERIODIC)

    def due(self, now_s: float) -> list[type[MillMessage]]:
        """The kinds due at ``now_s``; each is rescheduled one period on (re-phased after a long gap)."""
        kinds = []
        for kind in PERIODIC:
            next_s = self._next_s[kind]
            if next_s is None or now_s >= next_s - 1e-9:
                kinds.append(kind)
                period = self.period_s[kind]
                following = now_s + period if next_s is None else next_s + period
                self._next_s[kind] = following if following > now_s else now_s + period
        return kinds


PhysicsWorker = Literal["thread", "inline"]
"""Where the physics summary runs: on a worker thread, or inside the tick."""


class PhysicsCache:
    """The last physics summary, recomputed when the measured speeds moved enough.

    ``"inline"`` (default) computes in the tick: every summary the speeds ask for
    is computed (about 0.1 ms each, compiled), deterministic. ``"thread"`` runs it
    on a worker thread (:mod:`firmware_sim.physics_worker`) and the frame carries
    the latest finished summary; a summary asked for while the worker is busy is
    skipped. The compiled kernels are loaded (or compiled, once per machine) here,
    at construction, not in the first tick.
    """

    def __init__(self, config: MillConfig, *, worker: PhysicsWorker = "inline") -> None:
        self.model = MillModel.from_config(config)
        revolution_summary(self.model, 10.0, 80.0)  # load the compiled kernels before the first tick
        self._requested: tuple[float, float] | None = None
        self._frame = PhysicsTelemetry(False, 0.0, 0.0, 0.0, 0.0)
        self._worker = ThreadWorker(self.model) if worker == "thread" else None
        self.computations = 0
        self.broken = False
        """True after the worker failed; the last frame is then repeated."""

    def frame(self, codec: Codec, omega_r_rpm: float, omega_v_rpm: float) -> PhysicsTelemetry:
        """The PhysicsTelemetry for the measured speeds (rpm): the cached one unless they moved enough."""
        worker = self._worker
        if worker is not None:
            try:
                summary = worker.poll()
            except Exception as exc:  # a broken worker must not stop the node: keep the last frame
                log.warning("physics worker failed (%s: %s); physics telemetry is frozen", type(exc).__name__, exc)
                self.broken = True
                self.close()
                return self._frame
            if summary is not None:
                self._frame = _frame_of(codec, summary)
        last = self._requested
        moved = (
            last is None
            or abs(omega_r_rpm - last[0]) > PHYSICS_RECOMPUTE_RPM
            or abs(omega_v_rpm - last[1]) > PHYSICS_RECOMPUTE_RPM
        )
        if moved and not self.broken and (worker is None or not worker.busy):
            self._requested = (omega_r_rpm, omega_v_rpm)
            self.computations += 1
            omega_r, omega_v = rpm_to_rad_s(omega_r_rpm), rpm_to_rad_s(omega_v_rpm)
            if worker is None:
                self._frame = _frame_of(codec, revolution_summary(self.model, omega_r, omega_v))
            else:
                worker.submit(omega_r, omega_v)
        return self._frame

    def close(self) -> None:
        """Stop the worker."""
        if self._worker is not None:
            self._worker.close()
            self._worker = None


def _frame_of(codec: Codec, summary: RevolutionSummary) -> PhysicsTelemetry:
    """A level-(b) summary as a frame, saturated into the DBC ranges (nan → 0)."""
    theta_deg = math.degrees(summary.theta_d_rad) % 360.0 if summary.detached else 0.0

    def finite(value: float) -> float:
        return value if math.isfinite(value) else 0.0

    return codec.saturated(
        PhysicsTelemetry(
            detached=summary.detached,
            theta_d_deg=finite(theta_deg),
            impact_rate_hz=finite(summary.impact_rate_hz),
            impact_energy_mj=finite(summary.mean_impact_energy_j * 1e3),  # J → mJ
            shear_kpa=finite(summary.mean_shear_pa * 1e-3),  # Pa → kPa
            no_slip_violated=summary.no_slip_violated,
        )
    )


__all__ = ["PERIODIC", "PHYSICS_RECOMPUTE_RPM", "PhysicsCache", "PhysicsWorker", "Schedule"]
