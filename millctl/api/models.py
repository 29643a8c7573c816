"""Request and response models of the service API (``/v1``), defined once for every part of millctl.

Keys follow one scheme: ``<what>_<axis>_<unit>`` (``setpoint_rotary_rpm``,
``limit_rotary_rpm``, ``vibration_rpm``), units always last.

Every request is validated and unknown fields are refused; every float in a
response may be null where the value is not finite (e.g. an unbounded limit).
:class:`StatusOut` mirrors :class:`millctl.controller.Status` field for field
(a unit test holds them together).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationInfo

from millctl.api.enums import BusCondition, ControllerState, ErrorCode, EventKind, SimFaultName


class Strict(BaseModel):
    """A request or response body: unknown fields are an error."""

    model_config = ConfigDict(extra="forbid")


Rpm = Annotated[float, Field(ge=0.0, le=100_000.0, allow_inf_nan=False)]
RpmPerS = Annotated[float, Field(gt=0.0, le=100_000.0, allow_inf_nan=False)]


# ---------------------------------------------------------------- errors
class Refusal(Strict):
    """One quantity outside the envelope: its value, the limit and why."""

    quantity: str = Field(description="what was refused, e.g. omega_r_rpm, omega_v_rpm, temp_c")
    value: float | None = Field(description="the value asked for")
    limit: float | None = Field(description="the bound it crosses")
    unit: str = Field(description="unit of value and limit")
    reason: str = Field(description="the refusal in words, with the value, the bound and where to read more")


class ErrorBody(Strict):
    """Every error of the API: a stable code, a message naming the value and the bound, the field if any."""

    code: ErrorCode = Field(description="stable machine-readable code")
    message: str = Field(description="what was wrong, with the value and the bound")
    field: str | None = Field(default=None, description="the request field (or header) at fault")
    holder: str | None = Field(default=None, description="who holds control (code control_held)")
    refusals: list[Refusal] = Field(default_factory=list, description="the interlock's refusals (interlock_refused)")


# ---------------------------------------------------------------- status
class LinkOut(Strict):
    """Health of one telemetry frame kind."""

    age_s: float | None = Field(description="time since the last valid frame (s); null before the first")
    stale_after_s: float = Field(description="age past which it counts as stale (s)")
    stale: bool = Field(description="true when the last valid frame is older than stale_after_s")
    frames: int = Field(description="valid frames received")
    e2e: dict[str, int] = Field(description="E2E verdict counts (ok, repeated, wrong-crc …)")
    e2e_score: int = Field(description="the E2E receiver's net error score")
    e2e_sequence_score: int = Field(description="the E2E receiver's sequence score (repeated/out-of-sequence counters)")


class BusReceiveOut(Strict):
    """The controller's bus reader counts since start (:class:`millctl.protocol.ReceiveCounts`)."""

    frames: int = Field(description="frames read")
    estops: int = Field(description="E-stop frames (ID 0x000) read, from any sender")
    malformed: int = Field(description="frames that do not fit the DBC (length, DLC, FD, remote, unknown ID, value)")
    error_frames: int = Field(description="CAN error frames")
    receive_errors: int = Field(description="reads that failed (undecodable datagram, socket error)")
    capped_drains: int = Field(description="ticks whose drain stopped at its bound with frames left")
    last_error: str = Field(description="the latest receive error or malformed frame (empty before the first)")


class BusHealthOut(Strict):
    """The CAN controller's condition and error counts since start (:class:`millctl.protocol.bus_health.BusHealth`)."""

    interface: str = Field(description="the python-can interface (bus.interface)")
    condition: BusCondition = Field(description="error-active, error-warning, error-passive or bus-off")
    state_source: str = Field(description="how the condition is known: error frames, and the adapter's state "
                              "where its driver reports one")
    error_frames: int = Field(description="CAN error frames")
    bus_errors: int = Field(description="protocol violations and bus errors (bit, stuff, form, CRC)")
    ack_errors: int = Field(description="frames nobody acknowledged: no other node, or a wrong bitrate")
    arbitration_lost: int = Field(description="arbitration lost")
    controller_errors: int = Field(description="controller problems: overflows, warning and passive levels")
    tx_timeouts: int = Field(description="transmit timeouts")
    error_passive_count: int = Field(description="times the controller went error-passive")
    bus_off_count: int = Field(description="times the controller went bus-off (each trips)")
    restarts: int = Field(description="controller restarts after bus-off")
    tx_error_counter: int | None = Field(description="transmit error counter (TEC), null where not reported")
    rx_error_counter: int | None = Field(description="receive error counter (REC), null where not reported")
    last_error: str = Field(description="the latest error frame or state reading, in words (empty before the first)")


class DriveOut(Strict):
    """One drive in its backend's words (CiA 402: its power state, NMT state, heartbeat, identity, EMCY)."""

    name: str = Field(description="the motor it drives (rotary or vibration), or furnace: the millbus furnace node "
                      "beside CiA 402 drives on its own channel ([drives.furnace_bus])")
    state: str = Field(description="a drive's CiA 402 power state (statusword 0x6041), the furnace node's state "
                       "(NodeStatus), or unknown")
    node_id: int | None = Field(default=None, description="a drive's CANopen node ID; null on millbus and for the "
                                "furnace node")
    detail: str = Field(default="", description="a drive's NMT state, heartbeat age, identity 0x1018 and first EMCY; "
                        "the furnace node's channel, NodeStatus age and temperature")


class StatusOut(Strict):
    """A snapshot of the controller (as :class:`millctl.controller.Status`; non-finite floats as null)."""

    time_s: float | None = Field(description="controller clock (s)")
    state: ControllerState = Field(description="the controller's state (docs/safety.md#state-machine)")
    trip_cause: str = Field(description="why the controller tripped (empty unless TRIPPED)")
    node_state: str | None = Field(description="the node's own state, null before the node is seen")
    node_faults: list[str] = Field(description="fault flags the node reports")
    node_first_fault: str | None = Field(description="the node's first latched fault")
    refused_setpoints: int = Field(description="setpoints the node itself refused")
    last_refusal: str | None = Field(description="the node's last refusal code")
    setpoint_rotary_rpm: float | None = Field(description="rotary setpoint sent now (rpm, on the ramp)")
    setpoint_vibration_rpm: float | None = Field(description="vibration setpoint sent now (rpm, on the ramp)")
    target_rotary_rpm: float | None = Field(description="rotary speed at the end of the ramp (rpm)")
    target_vibration_rpm: float | None = Field(description="vibration speed at the end of the ramp (rpm)")
    ramp_remaining_s: float | None = Field(description="time left on the ramp (s)")
    measured_rotary_rpm: float | None = Field(description="measured rotary speed ω_r (rpm)")
    measured_vibration_rpm: float | None = Field(description="measured vibration speed ω_v (rpm)")
    rotary_torque_nm: float | None = Field(description="rotary drive torque (N·m)")
    vibration_torque_nm: float | None = Field(description="vibration drive torque (N·m)")
    furnace_target_c: float | None = Field(description="furnace target (°C), null with the heater off")
    furnace_setpoint_c: float | None = Field(description="furnace setpoint now, on its heating ramp (°C)")
    furnace_temp_c: float | None = Field(description="measured furnace temperature (°C)")
    heater_pct: float | None = Field(description="heater power (%)")
    heater_on: bool | None = Field(description="heater switch as the node reports it; null before telemetry")
    law: str = Field(description="the envelope's limit law (docs/safety.md)")
    margin: float | None = Field(description="safety margin applied to the law (fraction)")
    limit_rotary_rpm: float | None = Field(description="enforced rotary limit at the vibration setpoint (rpm)")
    margin_rpm: float | None = Field(description="limit minus the rotary speed (rpm); null at standstill")
    law_is_every_cycle: bool = Field(description="true where the law bounds detachment on every cycle")
    detached: bool | None = Field(description="the node's physics: rods detach from the wall")
    theta_d_deg: float | None = Field(description="detachment angle θ_d (deg)")
    impact_rate_hz: float | None = Field(description="impacts per second")
    impact_energy_mj: float | None = Field(description="mean impact energy (mJ)")
    shear_kpa: float | None = Field(description="shear stress (kPa)")
    link: dict[str, LinkOut] = Field(description="health of each telemetry frame kind")
    invalid_frames: int = Field(description="frames dropped as invalid")
    receive_errors: int = Field(description="failed reads and CAN error frames, counted and skipped")
    bus_receive: BusReceiveOut = Field(description="every count of the controller's bus reader")
    bus_health: BusHealthOut = Field(description="the CAN controller's condition and error counts")
    drives_backend: str = Field(default="millbus", description="what the drives are behind: millbus or cia402")
    drives: list[DriveOut] = Field(default_factory=list, description="each drive in its backend's words "
                                   "(empty on millbus, where node_state is the drives' state)")


# ---------------------------------------------------------------- envelope
class EnvelopePoint(Strict):
    """The enforced limit at one vibration speed."""

    vibration_rpm: float = Field(description="vibration speed ω_v (rpm)")
    limit_rotary_rpm: float | None = Field(description="enforced rotary limit, margin applied (rpm)")
    law_limit_rotary_rpm: float | None = Field(description="the law's rotary limit without margin (rpm)")
    law_is_every_cycle: bool = Field(description="true where the law bounds detachment on every cycle")
    laws_rotary_rpm: dict[str, float | None] = Field(
        default_factory=dict, description="every limit law's rotary limit without margin, by law name (rpm)")


class RegimeOut(Strict):
    """Where the law in force is not the every-cycle detachment bound (millctl.safety.regime, docs/model.md#eq-9)."""

    above_vibration_rpm: float = Field(description="from this vibration speed up (rpm; 0: everywhere)")
    summary: str = Field(description="the warning in one short line")
    message: str = Field(description="the warning in full: where, why, what it means")


class EnvelopeOut(Strict):
    """The limit curve the interlock enforces, and what it is built from (SAFETY 14: shown)."""

    law: str = Field(description="the limit law in force")
    description: str = Field(description="the envelope in words")
    margin: float = Field(description="safety margin applied to the law (fraction)")
    rotary_max_rpm: float = Field(description="rotary drive maximum (rpm)")
    vibration_max_rpm: float = Field(description="vibration drive maximum (rpm)")
    furnace_min_c: float = Field(description="lowest furnace target (°C)")
    furnace_max_c: float = Field(description="highest furnace target (°C)")
    max_heating_rate_c_per_min: float = Field(description="fastest heating ramp (°C/min)")
    points: list[EnvelopePoint] = Field(description="the limit curve: one point per vibration speed of the grid")
    regime: RegimeOut | None = Field(default=None, description="where the law is not the every-cycle bound; "
                                     "null where it is over the whole drive range")


class CheckRequest(Strict):
    """An operating point to check against the envelope (nothing is commanded)."""

    rotary_rpm: float = Field(allow_inf_nan=False, ge=-100_000.0, le=100_000.0, description="ω_r (rpm)")
    vibration_rpm: float = Field(allow_inf_nan=False, ge=-100_000.0, le=100_000.0, description="ω_v (rpm)")
    temp_c: float | None = Field(default=None, allow_inf_nan=False, ge=-1_000.0, le=10_000.0,
                                 description="furnace target (°C), if any")


class CheckOut(Strict):
    """The envelope's verdict on one point."""

    ok: bool = Field(description="true when the interlock allows the point (no refusals)")
    reason: str = Field(description="the verdict in words")
    limit_rotary_rpm: float | None = Field(description="enforced rotary limit at this ω_v (rpm)")
    margin_rpm: float | None = Field(description="limit minus ω_r (rpm)")
    refusals: list[Refusal] = Field(description="every reason it is refused: quantity, value, limit")


# ---------------------------------------------------------------- control lease
class TakeRequest(Strict):
    """Ask for control; ``force`` takes over a lease whose holder stopped renewing it (never a live one)."""

    force: bool = Field(default=False, description="take over an expired lease")


class LeaseOut(Strict):
    """The control lease: send ``lease_id`` in the ``X-Millctl-Lease`` header of every command."""

    lease_id: str = Field(description="the lease token: send it as X-Millctl-Lease with every command")
    holder: str = Field(description="who holds it, as api:<client name>")
    expires_in_s: float = Field(description="time until it expires unless renewed (s)")
    ttl_s: float = Field(description="lease time to live (s)")


class ControlOut(Strict):
    """Who holds control now (no lease id: only its holder knows it)."""

    held: bool = Field(description="true while a client holds the control lease")
    holder: str | None = Field(description="the client name of the lease's holder; null when nobody holds it")
    expires_in_s: float | None = Field(description="time until the lease expires (s)")
    expired: bool = Field(description="true when the holder stopped renewing: `force` may take it over")


# ---------------------------------------------------------------- commands
def _rate_needs_target(rate_c_per_min: float | None, info: ValidationInfo) -> float | None:
    """A heating rate with no furnace target (``temp_c`` null) is refused, not ignored: all or nothing."""
    if rate_c_per_min is not None and "temp_c" in info.data and info.data["temp_c"] is None:
        raise ValueError(
            f"heating rate {rate_c_per_min} °C/min given without a furnace target (body.temp_c): there is "
            "nothing to heat to, and the rate would be ignored; give the target with it, or leave the rate out"
        )
    return rate_c_per_min


HeatingRate = Annotated[
    Annotated[float, Field(allow_inf_nan=False, gt=0.0, le=10_000.0)] | None, AfterValidator(_rate_needs_target)
]
"""A heating rate (°C/min) of a request that also has ``temp_c``: refused when ``temp_c`` is null."""


class SetpointsRequest(Strict):
    """New drive speeds; the controller plans a ramp inside the envelope or refuses."""

    rotary_rpm: Rpm = Field(description="rotary target ω_r (rpm)")
    vibration_rpm: Rpm = Field(description="vibration target ω_v (rpm)")
    rotary_rate_rpm_s: RpmPerS | None = Field(default=None, description="rotary ramp rate (rpm/s); default: config")
    vibration_rate_rpm_s: RpmPerS | None = Field(default=None,
                                                 description="vibration ramp rate (rpm/s); default: config")
    linear: bool = Field(default=False, description="ramp both drives on one straight line (docs/safety.md)")
    temp_c: float | None = Field(default=None, allow_inf_nan=False, ge=-1_000.0, le=10_000.0,
                                 description="furnace target (°C) set with the speeds, all or nothing: "
                                 "when any part is refused, no part is applied")
    rate_c_per_min: HeatingRate = Field(default=None, description="heating rate with temp_c (°C/min); default: "
                                        "config. Without temp_c: 422, nothing applied")


class FurnaceRequest(Strict):
    """A furnace target (°C), or null to turn the heater off."""

    temp_c: float | None = Field(allow_inf_nan=False, ge=-1_000.0, le=10_000.0, description="target (°C)")
    rate_c_per_min: HeatingRate = Field(default=None, description="heating rate (°C/min); default: config. "
                                        "With temp_c null (heater off): 422, nothing applied")


class CommandOut(Strict):
    """A command was accepted: what was done and the state right after."""

    accepted: Literal[True] = Field(default=True, description="always true (a refusal is an error answer)")
    message: str = Field(description="the command as done")
    state: ControllerState = Field(description="the controller's state after the command took effect")
    duration_s: float | None = Field(default=None, description="planned ramp duration (setpoints)")


# ---------------------------------------------------------------- events, service
class EventOut(Strict):
    """One recorded event (state change, command, refusal, trip, control, service)."""

    seq: int = Field(description="sequence number (the stream's event id)")
    t: float = Field(description="Unix time (s)")
    time_s: float | None = Field(description="controller clock (s)")
    kind: EventKind = Field(description="what kind of event (state, command, refusal, trip, control, service …)")
    source: str = Field(description="who caused it: operator, recipe, interlock, node, service, api:<client>")
    message: str = Field(description="what happened, in words")
    data: dict[str, Any] = Field(description="the event's details (keys carry units: rotary_rpm)")


class EventsOut(Strict):
    """Events after a sequence number, oldest first (a ring buffer: old ones drop out)."""

    events: list[EventOut] = Field(description="the recorded events after the requested sequence number, oldest first")
    last_seq: int = Field(description="sequence number of the newest event")


class ServiceOut(Strict):
    """The running service: which mill it controls, its process, config, envelope law and margin, records."""

    mill_name: str = Field(description="the config's name of the mill")
    simulated: bool = Field(description="true when the node is the embedded simulation, not a real mill")
    pid: int = Field(description="the service's process id")
    version: str = Field(description="millctl's version")
    started_unix: float = Field(description="Unix time the service started (s)")
    config_path: str = Field(description="the configuration file the service loaded")
    config_sha256: str = Field(description="SHA-256 of that file's bytes")
    law: str = Field(description="the envelope law enforced (e.g. paper-eq9)")
    margin: float = Field(description="the safety margin kept below the law's limit (fraction, 0.1 = 10 %)")
    bus_interface: str = Field(description="the python-can interface of the CAN bus")
    bus_channel: str = Field(description="the CAN bus channel")
    embedded_node: bool = Field(description="the simulated node runs inside the service")
    socket_path: str = Field(description="the Unix socket the API is served on")
    records_dir: str = Field(description="the folder of the records (events.jsonl, bus/, runs/)")
    bus_log: str = Field(description="this session's bus log file")
    fault_injection: bool = Field(default=False, description="an instructor may inject the simulated node's faults "
                                  "(serve --fault-injection; only on a simulated mill): /v1/sim/faults exists")
    warnings: list[str] = Field(default_factory=list, description="what the operator must know about the service "
                                "itself, e.g. records that cannot be written (the mill is controlled as before), "
                                "or an interrupted run waiting to be resumed")
    unfinished_runs: list[str] = Field(default_factory=list, description="ids of the interrupted runs in the records "
                                       "(`millctl recipe list`, GET /v1/recipe/unfinished)")


# ---------------------------------------------------------------- fault drills (serve --fault-injection)
class FaultRequest(Strict):
    """Inject (or clear) one fault of the simulated node; ``CLEAR`` clears them all."""

    fault: SimFaultName = Field(description="the fault (docs/operations.md#fault-injection)")
    active: bool = Field(default=True, description="true injects it, false clears it")
    param: float = Field(default=0.0, allow_inf_nan=False, ge=-1e6, le=1e6,
                         description="its parameter: rpm, a probability 0–1, Hz or a heater mode, by fault")


class FaultsOut(Strict):
    """The faults injected into the simulated node now, with their parameter."""

    active: dict[SimFaultName, float] = Field(description="injected fault → its parameter")


__all__ = [
    "BusHealthOut",
    "CheckOut",
    "CheckRequest",
    "CommandOut",
    "ControlOut",
    "DriveOut",
    "EnvelopeOut",
    "EnvelopePoint",
    "ErrorBody",
    "EventOut",
    "EventsOut",
    "FaultRequest",
    "FaultsOut",
    "FurnaceRequest",
    "LeaseOut",
    "LinkOut",
    "Refusal",
    "RegimeOut",
    "ServiceOut",
    "SetpointsRequest",
    "StatusOut",
    "Strict",
    "TakeRequest",
]
