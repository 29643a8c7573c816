"""The controller's status snapshot: state, setpoints, measurements, envelope margin, link health."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

from millctl.protocol import FaultCode, FaultFlag, PhysicsTelemetry, RefusalCode

if TYPE_CHECKING:
    from millctl.controller.controller import Controller


@dataclass(frozen=True)
class Status:
    """Everything an operator or a client needs to see, as plain data (JSON-ready via :meth:`as_dict`)."""

    time_s: float
    state: str
    trip_cause: str
    node_state: str | None
    node_faults: list[str]
    node_first_fault: str | None
    refused_setpoints: int
    last_refusal: str | None
    setpoint_rotary_rpm: float
    setpoint_vibration_rpm: float
    target_rotary_rpm: float
    target_vibration_rpm: float
    ramp_remaining_s: float
    measured_rotary_rpm: float | None
    measured_vibration_rpm: float | None
    rotary_torque_nm: float | None
    vibration_torque_nm: float | None
    furnace_target_c: float | None
    furnace_setpoint_c: float | None
    furnace_temp_c: float | None
    heater_pct: float | None
    heater_on: bool | None
    law: str
    margin: float
    limit_rotary_rpm: float
    """The enforced rotary limit at the current vibration setpoint (rpm)."""
    margin_rpm: float | None
    """Limit minus the measured (or commanded) rotary speed (rpm); None at standstill."""
    law_is_every_cycle: bool
    detached: bool | None
    theta_d_deg: float | None
    impact_rate_hz: float | None
    impact_energy_mj: float | None
    shear_kpa: float | None
    link: dict[str, dict[str, object]]
    invalid_frames: int
    """Frames read that do not fit the DBC (malformed, unknown, FD, remote): counted and dropped."""
    receive_errors: int
    """Reads that failed (undecodable datagrams, socket errors) plus CAN error frames: counted, skipped."""
    bus_receive: dict[str, int | str]
    """Every count of the controller's bus reader (:class:`millctl.protocol.ReceiveCounts`)."""
    bus_health: dict[str, int | str | None]
    """The CAN controller's condition and error counts (:class:`millctl.protocol.bus_health.BusHealth`)."""
    drives_backend: str = "millbus"
    """What the drives are behind (``[drives] backend``)."""
    drives: list[dict[str, Any]] = field(default_factory=list)
    """Each drive in its backend's words (:class:`millctl.drives.DriveInfo`; empty on millbus)."""

    def as_dict(self) -> dict[str, Any]:
        """The snapshot as a JSON-ready dict."""
        return asdict(self)


def build_status(c: Controller) -> Status:
    """Take a snapshot of a controller."""
    now = c.clock.now()
    node, measured, furnace = c.node_status, c.measured, c.furnace
    physics = c.tracker.tracks[PhysicsTelemetry].last
    physics = physics if isinstance(physics, PhysicsTelemetry) else None
    target = c.trajectory.end if c.trajectory is not None else c.commanded
    remaining = 0.0
    if c.trajectory is not None:
        remaining = max(c.trajectory.duration_s - (now - c._trajectory_start_s), 0.0)
    w_v = c.commanded.omega_v_rpm
    limit = float(c.envelope.omega_r_limit_rpm(w_v))
    w_r = measured.rotary_rpm if measured is not None else c.commanded.omega_r_rpm
    return Status(
        time_s=now,
        state=str(c.state),
        trip_cause=c.trip_cause,
        node_state=node.state.name if node else None,
        node_faults=[f.name or "" for f in FaultFlag if node and f in node.fault_bits],
        node_first_fault=FaultCode(node.first_fault).name if node else None,
        refused_setpoints=node.refused_setpoints if node else 0,
        last_refusal=RefusalCode(node.last_refusal).name if node else None,
        setpoint_rotary_rpm=c.commanded.omega_r_rpm,
        setpoint_vibration_rpm=c.commanded.omega_v_rpm,
        target_rotary_rpm=target.omega_r_rpm,
        target_vibration_rpm=target.omega_v_rpm,
        ramp_remaining_s=remaining,
        measured_rotary_rpm=measured.rotary_rpm if measured else None,
        measured_vibration_rpm=measured.vibration_rpm if measured else None,
        rotary_torque_nm=measured.rotary_torque_nm if measured else None,
        vibration_torque_nm=measured.vibration_torque_nm if measured else None,
        furnace_target_c=c.furnace_target_c,
        furnace_setpoint_c=c.furnace_setpoint_c if c.furnace_target_c is not None else None,
        furnace_temp_c=furnace.temp_c if furnace else None,
        heater_pct=furnace.heater_pct if furnace else None,
        heater_on=furnace.heater_on if furnace else None,
        law=c.envelope.law.value,
        margin=c.envelope.margin,
        limit_rotary_rpm=limit,
        margin_rpm=None if w_r == 0.0 or math.isinf(limit) else limit - w_r,
        law_is_every_cycle=bool(c.envelope.every_cycle(w_v)),
        detached=physics.detached if physics else None,
        theta_d_deg=physics.theta_d_deg if physics else None,
        impact_rate_hz=physics.impact_rate_hz if physics else None,
        impact_energy_mj=physics.impact_energy_mj if physics else None,
        shear_kpa=physics.shear_kpa if physics else None,
        link=c.tracker.health(now),
        invalid_frames=c.invalid_frames,
        receive_errors=c.drives.counts.receive_errors + c.drives.counts.error_frames,
        bus_receive=c.drives.counts.as_dict(),
        bus_health=c.bus_health.health.as_dict(),
        drives_backend=c.drives.backend,
        drives=[asdict(info) for info in c.drives.describe()],
    )


__all__ = ["Status", "build_status"]
