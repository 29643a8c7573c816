"""Fault injection: what a ``SimFault`` frame (IDs 0x700–0x7FF) does to the simulated node.

Honoured only when the node was started with ``fault_injection=True``
(``--fault-injection``); otherwise every SimFault frame is ignored and
logged. ``active=False`` clears the named fault; ``CLEAR`` clears them all.
The meaning of ``param`` per fault, and the node's expected end state, are
in docs/operations.md ("Fault injection").
"""

from __future__ import annotations

import logging

import can
import numpy as np

from firmware_sim.drives import DrivePair
from firmware_sim.furnace import FurnaceModel
from millctl.config.models import MillConfig
from millctl.protocol.messages import SimFault, SimFaultCode

log = logging.getLogger(__name__)

RUNAWAY_DEFAULT_FACTOR = 1.25
"""ROTARY_RUNAWAY with param ≤ 0 runs away to this many times the rotary drive's absolute maximum."""
NOISY_DEFAULT_TOLERANCES = 10.0
"""SENSOR_NOISY with param ≤ 0 uses this many measurement tolerances as its noise (rpm)."""
BABBLE_ID = 0x001
"""Identifier of babble frames: just below the E-stop, above every real frame (never 0x000)."""
BABBLE_MAX_PER_TICK = 200
"""At most this many babble frames per tick, whatever the requested rate."""


class FaultInjector:
    """The active injected faults, applied to the drives and furnace and to the node's transmit side."""

    def __init__(
        self, config: MillConfig, drives: DrivePair, furnace: FurnaceModel, *, enabled: bool, seed: int
    ) -> None:
        self.enabled = enabled
        self._config = config
        self._drives = drives
        self._furnace = furnace
        self._rng = np.random.default_rng(seed + 1)
        self.active: dict[SimFaultCode, float] = {}
        """Active faults and their parameter."""
        self._babble_credit = 0.0
        self.ignored = 0
        """SimFault frames ignored because injection is disabled."""

    def handle(self, frame: SimFault) -> None:
        """Apply one SimFault frame (or log and ignore it when injection is disabled)."""
        if not self.enabled:
            self.ignored += 1
            log.warning("ignoring %s: fault injection is disabled (start the node with --fault-injection)", frame)
            return
        if frame.fault is SimFaultCode.CLEAR:
            for code in list(self.active):
                self._set(code, False, 0.0)
        else:
            self._set(frame.fault, frame.active, frame.param)
        log.warning(
            "fault injection: %s %s (param %g); active now: %s",
            frame.fault.name,
            "on" if frame.active else "off",
            frame.param,
            sorted(c.name for c in self.active) or "none",
        )

    def _set(self, code: SimFaultCode, on: bool, param: float) -> None:
        drives, furnace = self._drives, self._furnace
        if on:
            self.active[code] = param
        else:
            self.active.pop(code, None)
        if code is SimFaultCode.VIB_STALL:
            drives.vibration.stalled = on
        elif code is SimFaultCode.ROTARY_RUNAWAY:
            default = RUNAWAY_DEFAULT_FACTOR * self._config.drives.rotary.max_speed_rpm
            drives.rotary.runaway_rpm = (param if param > 0.0 else default) if on else None
        elif code is SimFaultCode.SENSOR_STUCK:
            drives.rotary.sensor_stuck_rpm = drives.rotary.measured_rpm if on else None
            drives.vibration.sensor_stuck_rpm = drives.vibration.measured_rpm if on else None
        elif code is SimFaultCode.SENSOR_NOISY:
            default = NOISY_DEFAULT_TOLERANCES * self._config.interlock.measurement_tolerance_rpm
            noise = (param if param > 0.0 else default) if on else None
            drives.rotary.sensor_noise_rpm = noise
            drives.vibration.sensor_noise_rpm = noise
        elif code is SimFaultCode.HEATER_FAIL:
            furnace.element_open = on and param == 0.0
            furnace.relay_welded = on and param != 0.0

    def is_active(self, code: SimFaultCode) -> bool:
        """True while ``code`` is injected."""
        return code in self.active

    @property
    def silent(self) -> bool:
        """True while the node must not transmit anything (NODE_SILENT)."""
        return SimFaultCode.NODE_SILENT in self.active

    def _probability(self, code: SimFaultCode) -> float:
        return min(max(self.active.get(code, 0.0), 0.0), 1.0)

    def transmit(self, frame: can.Message) -> can.Message | None:
        """The frame as it leaves the node: None when lost (TX_LOSS), one bit flipped when corrupted (TX_CORRUPT)."""
        if self.silent:
            return None
        if SimFaultCode.TX_LOSS in self.active and self._rng.random() < self._probability(SimFaultCode.TX_LOSS):
            return None
        if SimFaultCode.TX_CORRUPT in self.active and self._rng.random() < self._probability(SimFaultCode.TX_CORRUPT):
            data = bytearray(frame.data)
            bit = int(self._rng.integers(0, 8 * len(data)))
            data[bit // 8] ^= 1 << (bit % 8)
            frame = can.Message(
                arbitration_id=frame.arbitration_id, data=bytes(data), is_extended_id=False, dlc=len(data)
            )
        return frame

    def babble(self, dt_s: float) -> list[can.Message]:
        """Junk frames due in this tick at the NODE_BABBLE rate (param Hz, capped per tick)."""
        if SimFaultCode.NODE_BABBLE not in self.active or self.silent:
            self._babble_credit = 0.0
            return []
        rate_hz = max(self.active[SimFaultCode.NODE_BABBLE], 0.0)
        self._babble_credit = min(self._babble_credit + rate_hz * dt_s, float(BABBLE_MAX_PER_TICK))
        count = int(self._babble_credit)
        self._babble_credit -= count
        payloads = self._rng.integers(0, 256, size=(count, 8), dtype=np.uint8)
        return [
            can.Message(arbitration_id=BABBLE_ID, data=bytes(row.tobytes()), is_extended_id=False, dlc=8)
            for row in payloads
        ]


__all__ = [
    "BABBLE_ID",
    "BABBLE_MAX_PER_TICK",
    "NOISY_DEFAULT_TOLERANCES",
    "RUNAWAY_DEFAULT_FACTOR",
    "FaultInjector",
]
