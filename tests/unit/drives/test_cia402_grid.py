"""SAFETY 21 on CiA 402 drives: what the interlock checks is what goes on the wire, at a drive's coarse velocity unit.

With units_per_rpm = 0.1 (one drive unit = 10 mill rpm) a setpoint checked on
the millbus 0.1 rpm grid could be rounded by the backend up to 5 rpm above
the eq. 9 limit; the planner now snaps onto the drive's own grid, and the
limits written by SDO are rounded down onto it.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from millctl.config import MillConfig, load_config
from millctl.config.models import Cia402Drive
from millctl.controller import ControllerState
from millctl.drives.cia402.limits import drive_limits
from millctl.safety import Envelope, InterlockRefused, RampPlanner, SpeedPoint
from millctl.safety.grid import MILLBUS_RESOLUTION_RPM, DriveGrid, ScaledGrid
from tests.unit.drives.rig402 import Rig402

S = ControllerState

ROTARY_UNITS_PER_RPM = 0.1
"""One rotary drive unit = 10 mill rpm (gear ratio 1)."""


def _coarse_config(tmp_path: Path, gear_ratio: float = 1.0) -> MillConfig:
    text = Path("config/mill-cia402.toml").read_text()
    rotary = text.index("[drives.rotary.cia402]")
    head, tail = text[:rotary], text[rotary:]
    tail = tail.replace("units_per_rpm = 1.0", f"units_per_rpm = {ROTARY_UNITS_PER_RPM}", 1)
    tail = tail.replace("gear_ratio = 1.0", f"gear_ratio = {gear_ratio}", 1)
    (tmp_path / "mill.toml").write_text(head + tail)
    return load_config(tmp_path / "mill.toml").config


@pytest.fixture
def coarse(tmp_path: Path) -> Iterator[Rig402]:
    rig = Rig402(_coarse_config(tmp_path))
    yield rig
    rig.close()


def _rpdo_pairs(rig: Rig402) -> list[tuple[float, float]]:
    """Every (rotary, vibration) target the controller sent, as each drive reads it back (mill rpm)."""
    rotary, vibration = rig.config.drives.rotary.cia402, rig.config.drives.vibration.cia402
    assert rotary is not None and vibration is not None
    pairs: list[tuple[float, float]] = []
    r_units: int | None = None
    for frame in rig.heard:
        if frame.arbitration_id == 0x200 + rotary.node_id:
            r_units = struct.unpack_from("<Hi", frame.data)[1]
        elif frame.arbitration_id == 0x200 + vibration.node_id and r_units is not None:
            v_units = struct.unpack_from("<Hi", frame.data)[1]  # sent right after the rotary's, in one batch
            pairs.append((rotary.mill_rpm(r_units), vibration.mill_rpm(v_units)))
    return pairs


def test_every_rpdo_target_toward_the_eq9_boundary_is_inside_eq9_at_the_omega_v_it_was_sent_with(
    coarse: Rig402,
) -> None:
    rig = coarse
    envelope = rig.controller.envelope
    rig.arm()
    rig.heard.clear()
    accepted = []
    for rotary_rpm in (187.0, 189.9, 185.1, 180.0, 170.0):  # eq. 9 with margin at 800 rpm: 189.97 rpm
        if rig.controller.state is S.TRIPPED:
            break
        try:
            move = rig.controller.set_speeds(rotary_rpm, 800.0)
        except InterlockRefused:
            continue
        accepted.append(move.end.omega_r_rpm)
        rig.run(120.0, lambda: rig.controller.trajectory is None or rig.controller.state is S.TRIPPED)
        rig.run(1.0)
    pairs = _rpdo_pairs(rig)
    outside = [(r, v, envelope.limit_rpm(v)) for r, v in pairs if r > envelope.limit_rpm(v)]
    assert outside == []
    assert rig.controller.state is S.RUNNING, rig.controller.trip_cause
    assert accepted == [180.0, 170.0] and max(r for r, _ in pairs) == 180.0  # the mill did ramp to the boundary

def test_a_target_that_would_round_past_eq9_on_the_drives_grid_is_refused_naming_the_value_sent(
    coarse: Rig402,
) -> None:
    rig = coarse
    rig.arm()
    with pytest.raises(InterlockRefused) as refused:
        rig.controller.set_speeds(187.0, 800.0)
    assert "as sent on the wire's grid of 10 rpm (rotary) and 1 rpm (vibration): ω_r = 190 rpm" in str(refused.value)
    assert rig.controller.trajectory is None


@pytest.mark.parametrize("gear_ratio", [1.0, 3.0, 0.7])
def test_the_written_speed_caps_never_exceed_the_envelope_or_the_drives_max_speed(
    tmp_path: Path, gear_ratio: float
) -> None:
    config = _coarse_config(tmp_path, gear_ratio)
    envelope = Envelope.from_config(config)
    planner = RampPlanner.from_config(config, envelope)
    rotary = config.drives.rotary
    cia = rotary.cia402
    assert cia is not None
    for omega_v_rpm in (0.0, 300.0, 555.0, 800.0, 1000.0):
        units_per_mill_rpm = cia.gear_ratio * cia.units_per_rpm
        top = cia.mill_rpm(math.floor(envelope.limit_rpm(omega_v_rpm) * units_per_mill_rpm))  # on the drive's grid
        move = planner.plan(SpeedPoint(0.0, 0.0), SpeedPoint(top, omega_v_rpm))
        limits = {limit.index: limit.value for limit in drive_limits("rotary", rotary, cia, envelope, move)}
        eq9_rpm = envelope.limit_rpm(move.end.omega_v_rpm)  # the lowest ω_v of a move from standstill is 0
        cap_rpm = min(rotary.max_speed_rpm, max(envelope.limit_rpm(0.0), move.end.omega_r_rpm))
        assert cia.mill_rpm(limits[0x607F]) <= cap_rpm
        assert cia.mill_rpm(limits[0x607F]) >= move.end.omega_r_rpm  # never clips what the move commands
        assert move.end.omega_r_rpm <= eq9_rpm
        assert limits[0x6080] / cia.gear_ratio <= rotary.max_speed_rpm


def test_a_cap_on_the_drives_grid_is_written_as_itself_and_one_between_grid_steps_rounded_down(tmp_path: Path) -> None:
    config = _coarse_config(tmp_path)
    envelope = Envelope.from_config(config)
    rotary = config.drives.rotary
    cia = rotary.cia402
    assert cia is not None
    planner = RampPlanner.from_config(config, envelope)
    move = planner.plan(SpeedPoint(0.0, 0.0), SpeedPoint(180.0, 800.0))
    on_grid = {limit.index: limit.value for limit in drive_limits("rotary", rotary, cia, envelope, move)}
    assert on_grid[0x607F] == 18  # max(eq. 9 at ω_v = 0: 141.6 rpm, the move's 180 rpm) = 180 rpm = 18 units
    at_rest = {limit.index: limit.value for limit in drive_limits("rotary", rotary, cia, envelope, None)}
    assert envelope.limit_rpm(0.0) == pytest.approx(141.58, abs=0.01)
    assert at_rest[0x607F] == 14  # 141.58 rpm rounded down: 140 rpm, not the 150 rpm rounding up gave


@settings(max_examples=300, deadline=None)
@given(
    units_per_rpm=st.floats(1e-3, 1e4, allow_nan=False),
    gear_ratio=st.floats(0.05, 100.0, allow_nan=False),
    speed_rpm=st.floats(-2000.0, 2000.0, allow_nan=False),
)
def test_a_snapped_speed_is_exactly_what_the_drive_reads_back(
    units_per_rpm: float, gear_ratio: float, speed_rpm: float
) -> None:
    cia = Cia402Drive(node_id=2, units_per_rpm=units_per_rpm, gear_ratio=gear_ratio)
    grid = DriveGrid.for_drive(cia.units_per_mill_rpm)
    snapped = grid.snap(speed_rpm)
    assert cia.mill_rpm(cia.wire_velocity(snapped)) == snapped  # the round trip is the checked value, bit for bit
    assert abs(snapped - speed_rpm) <= grid.step_rpm / 2 * (1 + 1e-9)
    assert grid.step_rpm >= MILLBUS_RESOLUTION_RPM * (1 - 1e-9)  # never finer than the millbus grid
    assert cia.wire_velocity(snapped) % grid.stride == 0  # a whole number of grid steps in drive units
    assert grid.floor(abs(speed_rpm)) <= abs(speed_rpm)


def test_the_grid_is_the_drives_unit_or_the_fewest_whole_units_that_span_the_millbus_grid() -> None:
    assert DriveGrid.for_drive(0.1).step_rpm == pytest.approx(10.0)  # coarse: its own unit
    assert DriveGrid.for_drive(1.0).step_rpm == pytest.approx(1.0)
    assert DriveGrid.for_drive(100.0).stride == 10  # 0.01 rpm a unit: 10 units = 0.1 rpm
    assert DriveGrid.for_drive(33.0).stride == 4  # 4 units = 0.121 rpm ≥ 0.1 rpm
    millbus = RampPlanner.from_config(load_config("config/mill.toml").config)
    assert millbus.grids == (ScaledGrid(MILLBUS_RESOLUTION_RPM), ScaledGrid(MILLBUS_RESOLUTION_RPM))
    assert millbus.snap(SpeedPoint(123.45, 0.3)) == SpeedPoint(round(123.45 / 0.1) * 0.1, round(0.3 / 0.1) * 0.1)
