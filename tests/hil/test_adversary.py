"""The raw-CAN adversary against the mill: every frame suspect, no input fatal (issue 15, SAFETY 16, 17, 19, 22).

The service and the node run as separate processes on the transport under
test (udp_multicast inside ``tests/hil/in_netns``; socketcan in the VM); the
test process holds the probe (capture with receive timestamps) and the
adversary (``tests/hil/adversary.py``). Each scenario asserts the safe outcome
and prints its reaction time as ``HIL-TIMING {json}`` (docs/safety.md).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import can
import pytest

from firmware_sim.faults import BABBLE_ID
from millctl.protocol import (
    NO_FAULTS,
    Command,
    CommandCode,
    ControllerState,
    Decoded,
    DriveTelemetry,
    EStop,
    EStopSource,
    FaultCode,
    FaultFlag,
    Heartbeat,
    MillMessage,
    NodeState,
    NodeStatus,
    RefusalCode,
    Setpoints,
    SimFaultCode,
    sequence_decay_s,
)
from tests.hil.adversary import MAX_FRAME_RATE_HZ, Adversary, raw_frame
from tests.hil.conftest import pooled_mill
from tests.hil.mill_pool import MillKind
from tests.hil.scenario_support import (
    STANDSTILL_RPM,
    Mill,
    Probe,
    Seen,
    is_command,
    is_kind,
    is_status,
    load_scale,
    mill_on,
    report_timing,
    sequence_limit_reached_at,
    wait_for,
)
from tests.support.pace import cpu_share

if TYPE_CHECKING:
    from tests.hil.conftest import Spawner, Transport
    from tests.hil.mill_pool import MillPool

pytestmark = pytest.mark.hil

LOW_RPM = (60.0, 300.0)
"""ω_r, ω_v (rpm): the mill turning, short ramps."""
Capture = pytest.CaptureFixture[str]


NEEDS_A_BUS_NODE = "the adversary is a bus node of its own: python-can's virtual bus stays inside one process"


def _running(started: Mill) -> Iterator[tuple[Mill, Probe, Adversary]]:
    """``started`` RUNNING at ``LOW_RPM``, its probe, and an adversary on its bus (closed afterwards)."""
    assert started.probe is not None
    adversary = Adversary(started.config.bus, started.codec)
    try:
        started.run_at(*LOW_RPM)
        yield started, started.probe, adversary
    finally:
        adversary.close()


@pytest.fixture
def mill(
    request: pytest.FixtureRequest, transport: Transport, mill_pool: MillPool
) -> Iterator[tuple[Mill, Probe, Adversary]]:
    """The mill RUNNING at ``LOW_RPM`` on ``transport``, its probe, and the adversary (skipped on virtual).

    The module's shared mill (tests/hil/mill_pool.py): reset to DISABLED at rest after each scenario,
    restarted after a failure.
    """
    if not transport.crosses_processes:
        pytest.skip(NEEDS_A_BUS_NODE)
    with pooled_mill(request, mill_pool, MillKind(transport.name)) as started:
        yield from _running(started)


@pytest.fixture
def own_mill(transport: Transport, spawn: Spawner, tmp_path: Path) -> Iterator[tuple[Mill, Probe, Adversary]]:
    """Like ``mill``, started for this test alone: for the scenario that kills the service."""
    if not transport.crosses_processes:
        pytest.skip(NEEDS_A_BUS_NODE)
    with mill_on(transport, spawn, tmp_path) as started:
        yield from _running(started)


def wait_status(mill: Mill, probe: Probe, where: Callable[[Seen], bool], after: float, what: str) -> Seen:
    """The first frame after ``after`` matching ``where``; on timeout the failure shows the processes' output too."""
    try:
        return probe.wait_first(where, after, mill.timeout(3.0), what)
    except pytest.fail.Exception as failed:
        pytest.fail(f"{failed.msg}\n{mill._tail()}")


def processes_alive(mill: Mill) -> None:
    for name, proc in (("service", mill.service), ("node", mill.node)):
        assert proc is not None, f"no {name} process"
        assert proc.poll() is None, f"the {name} exited ({proc.returncode}):\n{mill._tail()}"


def reports_estop(seen: Seen) -> bool:
    """A NodeStatus with the E-stop latched: FAULT with the ESTOP bit, whichever fault came first (SAFETY 15)."""
    m = seen.message
    return isinstance(m, NodeStatus) and m.state is NodeState.FAULT and FaultFlag.ESTOP in m.fault_bits


def estop_reaction(
    mill: Mill, probe: Probe, adversary: Adversary, may_come_first: frozenset[FaultCode] = frozenset()
) -> float:
    """Send an E-stop from the adversary; return the time until the node reports it on the bus (s).

    The node's first fault must be the E-stop, or one of ``may_come_first``; the controller's trip must name it.
    """
    t_estop = adversary.send(adversary.forged(EStop(EStopSource.BUTTON)))
    seen = wait_status(mill, probe, reports_estop, t_estop, "NodeStatus FAULT with the ESTOP bit")
    report = seen.of(NodeStatus)
    first = FaultCode(report.first_fault)
    assert first in {FaultCode.ESTOP, *may_come_first}, (
        f"the node latched {first.name} before the E-stop ({report!r})\n{mill._tail()}"
    )
    cause = mill.wait_state("TRIPPED", 2.0)["trip_cause"]
    assert first.name in cause, f"the node's first fault was {first.name}, the controller's trip cause {cause!r}"
    return seen.t - t_estop


def assert_stops_inside(mill: Mill, probe: Probe, after: float) -> None:
    def still(seen: Seen) -> bool:
        m = seen.message
        return isinstance(m, DriveTelemetry) and max(abs(m.rotary_rpm), abs(m.vibration_rpm)) < STANDSTILL_RPM

    probe.wait_first(still, after, mill.timeout(20.0), "both drives at standstill")
    drives = probe.frames(after, lambda s: isinstance(s.message, DriveTelemetry))
    assert mill.outside_envelope(drives) == []


# --- drain fully, E-stop first (item 1) ---------------------------------------------------------------------------


@pytest.mark.parametrize("babble_hz", [100.0, 500.0, 1000.0])
def test_estop_under_a_babbling_node(
    mill: tuple[Mill, Probe, Adversary], transport: Transport, babble_hz: float, capsys: pytest.CaptureFixture[str]
) -> None:
    m, probe, adversary = mill
    t_babble = probe.inject(SimFaultCode.NODE_BABBLE, babble_hz / load_scale())  # the VM: relative to its speed now
    time.sleep(m.timeout(1.0))  # long enough for a backlog that a one-frame drain would have built
    assert probe.frames(t_babble, lambda s: s.frame.arbitration_id == BABBLE_ID), "the node babbled"
    measured_s = estop_reaction(m, probe, adversary)
    bound_s = m.bounds.node_reports_s
    report_timing(capsys, f"estop_under_babble_{babble_hz:.0f}hz", transport.name, measured_s, bound_s)
    assert measured_s <= bound_s
    assert_stops_inside(m, probe, t_babble)


def test_estop_inside_a_flood_on_0x001_at_the_buss_maximum_rate(
    mill: tuple[Mill, Probe, Adversary], transport: Transport, capsys: pytest.CaptureFixture[str]
) -> None:
    m, probe, adversary = mill
    # The bus's maximum rate as this machine can run it now: in the VM relative to its measured slowdown, and on
    # a loaded host times the CPU share a process gets. A flood the node's process cannot drain overflows its
    # socket's receive buffer, and the kernel drops datagrams, the E-stop among them: an artefact of emulating
    # CAN over UDP (on the wire, the E-stop wins arbitration). The E-stop's reaction bound stays physical.
    # The E-stop has a queue of its own where the kernel filters (SocketCAN: millctl.protocol.factory), the
    # controller's frames do not: a moment the node falls behind drops some, and the node may latch their loss
    # (WATCHDOG, or E2E_LINK from the counter jumps) before the E-stop, as a flood on the wire that starves
    # lower identifiers would. The E-stop must still be reported in time.
    rate_hz = MAX_FRAME_RATE_HZ / load_scale() * cpu_share()
    t_flood = time.monotonic()
    flood = adversary.flood(raw_frame(0x001, bytes(8), dlc=8), rate_hz)
    time.sleep(m.timeout(1.0))
    measured_s = estop_reaction(m, probe, adversary, frozenset({FaultCode.WATCHDOG, FaultCode.E2E_LINK}))
    sent = flood.stop()
    flood_hz = sent / (time.monotonic() - t_flood)
    bound_s = m.bounds.node_reports_s
    report_timing(capsys, "estop_in_flood_0x001", transport.name, measured_s, bound_s)
    assert flood_hz > 0.5 * rate_hz, (
        f"the flood ran at {flood_hz:.0f} of {rate_hz:.0f} frames/s ({flood.refused} refused)"
    )
    assert measured_s <= bound_s
    processes_alive(m)


# --- no input kills a loop (item 6) --------------------------------------------------------------------------------


def test_malformed_frames_and_datagrams_kill_no_loop(
    mill: tuple[Mill, Probe, Adversary], transport: Transport, capsys: pytest.CaptureFixture[str]
) -> None:
    m, probe, adversary = mill
    before = m.status()
    frames = adversary.malformed()
    datagrams = adversary.malformed_datagrams() if adversary.is_udp else {}
    for _ in range(20):
        adversary.send(*frames.values())
        if adversary.is_udp:
            adversary.datagrams(*datagrams.values())
        time.sleep(0.02)
    time.sleep(m.timeout(0.5))
    processes_alive(m)
    after = m.status()
    assert after["state"] == "RUNNING" and after["node_state"] == "RUNNING", after["trip_cause"]
    assert after["invalid_frames"] > before["invalid_frames"]
    if adversary.is_udp:
        # every datagram but the FD frame (malformed) is a receive error; the error frame counts with them
        assert after["receive_errors"] >= before["receive_errors"] + (len(datagrams) - 1) * 20
    # the loops are not only alive but responsive: an E-stop right behind the junk is acted on in time
    for _ in range(5):
        adversary.send(*frames.values())
    measured_s = estop_reaction(m, probe, adversary)
    bound_s = m.bounds.node_reports_s
    report_timing(capsys, "estop_behind_malformed_input", transport.name, measured_s, bound_s)
    assert measured_s <= bound_s
    processes_alive(m)


# --- E2E: bad CRC, counter jumps, a second sender (item 3) ----------------------------------------------------------


def assert_link_faults(
    mill: tuple[Mill, Probe, Adversary], frames: list[can.Message], name: str, transport: Transport, capsys: Capture
) -> None:
    """Send ``frames`` back to back: the node's link faults (NodeStatus FAULT/E2E_LINK) in time, the mill stops."""
    m, probe, adversary = mill
    t_first = adversary.send(*frames)
    seen = wait_status(m, probe, is_status(NodeState.FAULT, FaultCode.E2E_LINK), t_first, "NodeStatus FAULT/E2E_LINK")
    measured_s, bound_s = seen.t - t_first, m.bounds.node_reports_s
    report_timing(capsys, name, transport.name, measured_s, bound_s)
    assert measured_s <= bound_s
    assert "E2E_LINK" in m.wait_state("TRIPPED", 2.0)["trip_cause"]
    assert_stops_inside(m, probe, t_first)


def test_bad_crc_frames_fault_the_nodes_link(
    mill: tuple[Mill, Probe, Adversary], transport: Transport, capsys: Capture
) -> None:
    m, probe, adversary = mill
    bad = adversary.bad_crc(Setpoints(150.0, 300.0, 25.0, False))
    frames = [bad] * (m.config.interlock.e2e_error_limit + 1)
    assert_link_faults(mill, frames, "e2e_link_fault_on_bad_crc", transport, capsys)
    # A node already latched in another fault still latches and reports an E-stop in time, its first fault kept
    # (the path the flood scenario allows: the controller's frames lost before the E-stop latch E2E_LINK first).
    measured_s = estop_reaction(m, probe, adversary, frozenset({FaultCode.E2E_LINK}))
    first = FaultCode(probe.frames(where=reports_estop)[-1].of(NodeStatus).first_fault)
    assert first is FaultCode.E2E_LINK, f"the link fault came first, the node reports {first.name} first"
    bound_s = m.bounds.node_reports_s
    report_timing(capsys, "estop_after_link_fault", transport.name, measured_s, bound_s)
    assert measured_s <= bound_s


def test_counter_jumps_fault_the_nodes_link(
    mill: tuple[Mill, Probe, Adversary], transport: Transport, capsys: Capture
) -> None:
    m, _, adversary = mill
    limit = m.config.interlock.e2e_error_limit
    # good CRCs, every counter 5 past the last: out of sequence
    jumps = [adversary.forged(Heartbeat(ControllerState.RUNNING), (5 * k) % 16) for k in range(1, limit + 2)]
    assert_link_faults(mill, jumps, "e2e_link_fault_on_counter_jumps", transport, capsys)


ALL_WELL: dict[type[MillMessage], MillMessage] = {
    NodeStatus: NodeStatus(NodeState.RUNNING, NO_FAULTS, FaultCode.NONE, 0, RefusalCode.NONE),
    DriveTelemetry: DriveTelemetry(*LOW_RPM, 0.1, 0.1),
}


def test_a_second_sender_on_the_nodes_frames_trips_the_controller(
    mill: tuple[Mill, Probe, Adversary], transport: Transport, capsys: pytest.CaptureFixture[str]
) -> None:
    m, probe, adversary = mill

    def all_well(decoded: Decoded) -> MillMessage:
        return ALL_WELL[decoded.kind]

    t_start = probe.now()
    forger = adversary.answer((NodeStatus, DriveTelemetry), all_well)
    stop = probe.wait_first(is_command(CommandCode.STOP), t_start, m.timeout(5.0), "the controller's STOP")
    forged = forger.stop()
    assert forged > 0 and forger.first_sent_t is not None
    tripped = m.wait_state("TRIPPED", 2.0)
    assert "second sender" in tripped["trip_cause"], tripped["trip_cause"]
    # The reaction is timed from the frame that completed the evidence, as the bus carried it: the forger is
    # another process reading the bus, and how promptly it answers is the harness's speed, not the controller's
    # (timed from its first forgery, the same trip read 0.153-0.183 s against 6 periods and a tick, 0.18 s).
    interlock = m.config.interlock
    evidence = [
        sequence_limit_reached_at(
            probe.frames(t_start, is_kind(kind)),
            interlock.e2e_error_limit,
            interlock.e2e_sequence_decay_frames,
            sequence_decay_s(interlock.e2e_sequence_decay_frames, m.codec.cycle_time_s(kind) or 1.0),
        )
        for kind in (NodeStatus, DriveTelemetry)
    ]
    reached = [t for t in evidence if t is not None and t <= stop.t]

    def counters_seen() -> str:
        """Each identifier's counters as the probe captured them up to the STOP (+s, counter), for the failure."""
        return "; ".join(
            f"{kind.__name__}: "
            + " ".join(
                f"{s.t - t_start:+.4f}/{s.decoded.counter}"
                for s in probe.frames(t_start, is_kind(kind))
                if s.t <= stop.t and s.decoded is not None
            )
            for kind in (NodeStatus, DriveTelemetry)
        )

    assert reached, (
        f"the controller sent STOP at {stop.t - t_start:.3f} s with fewer than {interlock.e2e_error_limit} "
        f"repeated or out-of-sequence counters on the bus on either identifier ({forged} frames forged); "
        f"the probe captured {counters_seen()}"
    )
    measured_s = stop.t - min(reached)
    bound_s = m.bounds.controller_reacts_s
    report_timing(capsys, "trip_on_second_sender", transport.name, measured_s, bound_s)
    assert measured_s <= bound_s
    assert_stops_inside(m, probe, t_start)


# --- replayed heartbeats (item 4) ------------------------------------------------------------------------------


def test_replayed_heartbeats_after_the_service_is_killed_do_not_keep_the_mill_running(
    own_mill: tuple[Mill, Probe, Adversary], transport: Transport, capsys: pytest.CaptureFixture[str]
) -> None:
    m, probe, adversary = own_mill
    recording = adversary.record(Heartbeat, 16, m.timeout(5.0))
    assert len(recording) == 16, "16 heartbeats: a whole turn of the alive counter"
    # In a row, so that the loop's alive counters are always in sequence: E2E cannot tell this replay from
    # the controller, only the challenge can (a gap would fault the link on E2E and never test the echo).
    counters = [m.codec.decode(frame).counter for frame in recording]
    first = counters[0] or 0
    assert counters == [(first + k) % 16 for k in range(16)], f"a recording with gaps: alive counters {counters}"
    time.sleep(m.timeout(1.0))  # the recording ages: its challenges are superseded
    m.kill(m.service)
    t_dead = probe.frames(where=lambda s: isinstance(s.message, Heartbeat))[-1].t
    replay = adversary.replay(recording, m.config.timing.heartbeat_period_s)
    fault = wait_status(m, probe, is_status(NodeState.FAULT, FaultCode.WATCHDOG), t_dead, "NodeStatus FAULT/WATCHDOG")
    replayed = replay.stop()
    measured_s = fault.t - t_dead
    bound_s = m.bounds.watchdog_s
    report_timing(capsys, "watchdog_under_heartbeat_replay", transport.name, measured_s, bound_s)
    assert replayed > 0
    assert measured_s <= bound_s
    assert_stops_inside(m, probe, t_dead)


# --- forged commands (crafted with a good CRC and a fresh counter) ---------------------------------------------------


def test_forged_commands_out_of_place_are_refused_and_the_mill_runs_on(
    mill: tuple[Mill, Probe, Adversary], transport: Transport, capsys: pytest.CaptureFixture[str]
) -> None:
    m, probe, adversary = mill
    arm = probe.frames(where=is_command(CommandCode.ARM))[-1]
    assert arm.decoded is not None and arm.decoded.counter is not None
    refused_before = probe.latest(NodeStatus).refused_setpoints
    frames = [
        adversary.forged(Command(code), (arm.decoded.counter + k) % 16)
        for k, code in enumerate((CommandCode.RESET, CommandCode.DISARM), start=1)
    ]
    t_forged = adversary.send(*frames)

    def refused(seen: Seen) -> bool:
        s = seen.message
        return isinstance(s, NodeStatus) and (s.refused_setpoints - refused_before) % 256 >= 2

    seen = probe.wait_first(refused, t_forged, m.timeout(3.0), "NodeStatus counting both refusals")
    assert isinstance(seen.message, NodeStatus) and seen.message.last_refusal is RefusalCode.WRONG_STATE
    measured_s = seen.t - t_forged
    bound_s = m.bounds.node_reports_s
    report_timing(capsys, "forged_commands_refused", transport.name, measured_s, bound_s)
    assert measured_s <= bound_s
    status = wait_for(lambda: (s := m.status())["node_state"] == "RUNNING" and s, m.timeout(1.0), "RUNNING")
    assert status["state"] == "RUNNING" and status["node_state"] == "RUNNING"
    processes_alive(m)


# --- a fast forger against the node's rate bound (docs/operations.md#node-side-checks) -------------------------------


def test_a_fast_forger_cannot_walk_the_setpoint_faster_than_the_rate_bound(
    mill: tuple[Mill, Probe, Adversary], transport: Transport, capsys: Capture
) -> None:
    """1000 Setpoints frames a second, each 8 rpm of ω_v past the last, with fresh counters: the step limit that
    granted every frame a setpoint period's travel (18.2 rpm) let this walk ω_v at 8000 rpm/s; the node's rate
    bound lets the measured ω_v rise at most burst + 1.5 × max accel × the attack's length. The forger starts
    on hearing a genuine Setpoints frame (``Adversary.walk`` says why), so its burst moves the drive past the
    tolerance, and the controller, which never commanded that, trips."""
    m, probe, adversary = mill
    accel = m.config.drives.vibration.max_accel_rpm_s
    burst = 1.5 * accel * m.config.timing.watchdog_timeout_s + 0.2
    tolerance = m.config.interlock.measurement_tolerance_rpm
    forger = adversary.walk(Setpoints(*LOW_RPM, 25.0, False), (0.0, 8.0))
    wait_for(lambda: forger.first_sent_t, m.timeout(2.0), "the forger to hear the controller's Setpoints and start")
    time.sleep(0.3)
    forged = forger.stop()
    assert forged > 0 and forger.first_sent_t is not None and forger.last_sent_t is not None
    attack_s = forger.last_sent_t - forger.first_sent_t + m.bounds.scheduling_s
    allowed_rpm = LOW_RPM[1] + burst + 1.5 * accel * attack_s + tolerance
    time.sleep(m.timeout(1.0))
    drives = probe.frames(forger.first_sent_t, lambda s: isinstance(s.message, DriveTelemetry))
    peak_rpm = max(s.message.vibration_rpm for s in drives if isinstance(s.message, DriveTelemetry))
    with capsys.disabled():
        print(
            f"\nHIL-RATE fast forger on {transport.name}: {forged} frames in {attack_s:.3f} s, measured ω_v peak "
            f"{peak_rpm:.1f} rpm, bound {allowed_rpm:.1f} rpm (asked up to {LOW_RPM[1] + 8.0 * forged:.0f})"
        )
    assert peak_rpm <= allowed_rpm
    assert peak_rpm > LOW_RPM[1] + tolerance, f"the forgery moved ω_v less than the tolerance ({peak_rpm:.1f} rpm)"
    # the forged frames took the setpoint counters and outran the commands: the mill is stopped, inside
    assert m.wait_state("TRIPPED", m.timeout(3.0))["state"] == "TRIPPED"
    assert_stops_inside(m, probe, forger.first_sent_t)
    processes_alive(m)
