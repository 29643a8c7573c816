"""The node's periodic frames: when each is due, and the physics telemetry cache.

Periods come from the DBC (``Codec.cycle_time_s``): NodeStatus 20 Hz,
DriveTelemetry 50 Hz, FurnaceTelemetry and PhysicsTelemetry 10 Hz.
PhysicsTelemetry is the level-(b) summary of
:func:`millctl.physics.telemetry.revolution_summary` at the measured speeds;
one summary costs about a millisecond, so it is recomputed only when a speed
moved by more than ``PHYSICS_RECOMPUTE_RPM`` since the last one, only when
the frame is due, and on a worker thread — which keeps the 100 Hz tick budget.
"""

from __future__ import annotations

import math
from concurrent.futures import Future, ThreadPoolExecutor

from millctl.config.models import MillConfig
from millctl.physics.model import MillModel
from millctl.physics.telemetry import revolution_summary
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


class PhysicsCache:
    """The last physics summary, recomputed when the measured speeds moved enough.

    One summary takes 0.2 ms to ~100 ms (slowest at a crawl with fast
    vibration, where a rod's flight is long), far more than a 10 ms tick, so
    by default it runs on one worker thread and the frame carries the latest
    finished summary; ``threaded=False`` computes in the caller (deterministic,
    for tests).
    """

    def __init__(self, config: MillConfig, *, threaded: bool = True) -> None:
        self.model = MillModel.from_config(config)
        self._requested: tuple[float, float] | None = None
        self._frame = PhysicsTelemetry(False, 0.0, 0.0, 0.0, 0.0)
        self._pending: Future[PhysicsTelemetry] | None = None
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="physics") if threaded else None
        self.computations = 0

    def frame(self, codec: Codec, omega_r_rpm: float, omega_v_rpm: float) -> PhysicsTelemetry:
        """The PhysicsTelemetry for the measured speeds (rpm): the cached one unless they moved enough."""
        pending = self._pending
        if pending is not None and pending.done():
            self._frame = pending.result()
            self._pending = pending = None
        last = self._requested
        moved = (
            last is None
            or abs(omega_r_rpm - last[0]) > PHYSICS_RECOMPUTE_RPM
            or abs(omega_v_rpm - last[1]) > PHYSICS_RECOMPUTE_RPM
        )
        if moved and pending is None:
            self._requested = (omega_r_rpm, omega_v_rpm)
            self.computations += 1
            if self._executor is None:
                self._frame = _summarise(self.model, codec, omega_r_rpm, omega_v_rpm)
            else:
                self._pending = self._executor.submit(_summarise, self.model, codec, omega_r_rpm, omega_v_rpm)
        return self._frame

    def close(self) -> None:
        """Stop the worker thread (a running summary finishes; none is started)."""
        if self._executor is not None:
            self._executor.shutdown(wait=False, cancel_futures=True)


def _summarise(model: MillModel, codec: Codec, omega_r_rpm: float, omega_v_rpm: float) -> PhysicsTelemetry:
    """The level-(b) summary at the measured speeds (rpm) as a frame, saturated into the DBC ranges."""
    summary = revolution_summary(model, rpm_to_rad_s(omega_r_rpm), rpm_to_rad_s(omega_v_rpm))
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
        )
    )


__all__ = ["PERIODIC", "PHYSICS_RECOMPUTE_RPM", "PhysicsCache", "Schedule"]
