"""Frozen service answers for pictures that must not change between runs: an envelope, statuses, events, a lease."""

from __future__ import annotations

import asyncio
import math
from typing import Any

import httpx

from millctl.api import ControlOut, EnvelopeOut, EventOut, RecipeOut, ServiceOut, StatusOut
from millctl.config import load_config
from millctl.config.loader import packaged_file
from millctl.service import ServiceRuntime, create_app

SOCKET = "/run/millctl/test.sock"
T0_UNIX = 1_790_000_000.0
"""A fixed wall-clock time for the events (shown in UTC by the snapshot test)."""


def envelope_answer(points: int = 161) -> EnvelopeOut:
    """What ``GET /v1/envelope`` answers for the packaged config (Set A, paper eq. 9, margin 5 %).

    Asked of the service's own app, in-process and without a node, so the pictures show what the
    service really sends (not a copy of its handler that could drift from it).
    """
    runtime = ServiceRuntime(load_config(packaged_file("mill.toml")), embed_node=False)

    async def ask() -> httpx.Response:
        transport = httpx.ASGITransport(app=create_app(runtime))
        async with httpx.AsyncClient(transport=transport, base_url="http://millctl") as http:
            return await http.get("/v1/envelope", params={"points": points})

    try:
        response = asyncio.run(ask())
    finally:
        runtime.close()
    assert response.status_code == 200, response.text
    return EnvelopeOut.model_validate(response.json())


def link(age_s: float, frames: int, errors: int = 0) -> dict[str, Any]:
    """One frame kind's health."""
    return {"age_s": age_s, "stale_after_s": 1.0, "stale": age_s > 1.0, "frames": frames,
            "e2e": {"ok": frames - errors, "wrong-sequence": errors} if errors else {"ok": frames},
            "e2e_score": errors, "e2e_sequence_score": errors}


def status_at(i: int, *, state: str = "RUNNING", trip_cause: str = "") -> StatusOut:
    """The i-th of a run near the paper's operating point: ramping up to ω_r 180, ω_v 800 rpm, furnace to 600 °C."""
    ramp = min(i / 30.0, 1.0)
    rot, vib = 180.0 * ramp, 800.0 * min(i / 20.0, 1.0)
    wobble = 1.5 * math.sin(i)
    return StatusOut.model_validate({
        "time_s": 100.0 + 0.25 * i, "state": state, "trip_cause": trip_cause, "node_state": state,
        "node_faults": ["STALL"] if trip_cause else [], "node_first_fault": "STALL" if trip_cause else "NONE",
        "refused_setpoints": 0, "last_refusal": "NONE",
        "setpoint_rotary_rpm": rot, "setpoint_vibration_rpm": vib,
        "target_rotary_rpm": 180.0, "target_vibration_rpm": 800.0, "ramp_remaining_s": max(7.5 - 0.25 * i, 0.0),
        "measured_rotary_rpm": max(rot + wobble, 0.0), "measured_vibration_rpm": max(vib - wobble, 0.0),
        "rotary_torque_nm": 0.0, "vibration_torque_nm": 0.1,
        "furnace_target_c": 600.0, "furnace_setpoint_c": 25.0 + 2.0 * i, "furnace_temp_c": 25.0 + 1.8 * i,
        "heater_pct": 62.0, "heater_on": True,
        "law": "paper-eq9", "margin": 0.05, "limit_rotary_rpm": 189.97, "margin_rpm": 189.97 - rot - wobble,
        "law_is_every_cycle": vib < 300.0,
        "detached": True, "theta_d_deg": 131.4, "impact_rate_hz": 26.7, "impact_energy_mj": 0.42, "shear_kpa": 8.1,
        "link": {"NodeStatus": link(0.03, 900), "DriveTelemetry": link(0.01, 2250),
                 "FurnaceTelemetry": link(1.6, 450), "PhysicsTelemetry": link(9.0, 90, errors=2)},
        "invalid_frames": 0, "receive_errors": 0,
        "bus_receive": {"frames": 3690, "estops": 0, "malformed": 0, "error_frames": 0, "receive_errors": 0,
                        "capped_drains": 0, "last_error": ""},
        "bus_health": {"interface": "socketcan", "condition": "error-active",
                       "state_source": "error frames", "error_frames": 0, "bus_errors": 0, "ack_errors": 0,
                       "arbitration_lost": 0, "controller_errors": 0, "tx_timeouts": 0, "error_passive_count": 0,
                       "bus_off_count": 0, "restarts": 0, "tx_error_counter": None, "rx_error_counter": None,
                       "last_error": ""},
    })


CONTROL = ControlOut(held=True, holder="api:cli@bench", expires_in_s=21.0, expired=False)
RECIPE = RecipeOut.model_validate({"active": True, "progress": {
    "run_id": "20260101T000000Z-demo", "recipe": "demo", "recipe_file": "config/recipes/demo.toml", "state": "RUNNING",
    "reason": "", "step": 3, "steps": 6, "kind": "ramp", "elapsed_s": 20.0, "step_elapsed_s": 2.0,
    "remaining_s": 95.0, "record": "var/records/runs/x.jsonl"}})
EVENTS = [EventOut.model_validate({"time_s": None, "data": {}, **e}) for e in [
    {"seq": 1, "t": T0_UNIX, "kind": "service", "source": "service", "message": "service started (pid 4242)"},
    {"seq": 2, "t": T0_UNIX + 2, "kind": "control", "source": "api:cli@bench", "message": "control taken by cli"},
    {"seq": 3, "t": T0_UNIX + 3, "kind": "state", "source": "controller", "message": "DISABLED → ARMED: node ARMED"},
    {"seq": 4, "t": T0_UNIX + 4, "kind": "command", "source": "api:cli@bench",
     "message": "ramp to ω_r = 180.0 rpm, ω_v = 800.0 rpm over 12.1 s"},
    {"seq": 5, "t": T0_UNIX + 5, "kind": "refusal", "source": "api:cli@bench",
     "message": "ω_r = 250.0 rpm exceeds the limit 190.0 rpm at ω_v = 800.0 rpm"},
]]
ENVELOPE = envelope_answer()


def service_answer(*, fault_injection: bool = False) -> ServiceOut:
    """What ``GET /v1/service`` answers for a simulated mill (fixed pid, times and paths)."""
    return ServiceOut(
        mill_name="vibratory rod mill, Set A", simulated=True, pid=4242, version="0", started_unix=T0_UNIX,
        config_path="/etc/millctl/mill.toml", config_sha256="0" * 64, law="paper-eq9", margin=0.05,
        bus_interface="virtual", bus_channel="millbus", embedded_node=True, socket_path=SOCKET,
        records_dir="/var/lib/millctl/records", bus_log="/var/lib/millctl/records/bus/millbus.log",
        fault_injection=fault_injection,
    )
