"""A fast forger on the Setpoints identifier, against the real node and controller (SAFETY 12 and 18).

The forger sends 1000 Setpoints frames a second, each 8 rpm of ω_v past the
last, with the alive counters that follow the controller's. The node's rate
bound (firmware_sim/motion.py) lets at most its burst through; what it lets
through moves the drive past the measurement tolerance, and the controller,
which never commanded it, trips.

When the attack starts decides what the burst does. The controller's next
frame may land inside the burst with a counter that happens to be fresh (+1 …
+3 past the forged one): the node then takes it, and the step back to the
genuine setpoint still fits the rate bound, so the forgery is undone within
milliseconds. The drive moves less than the tolerance, and the measured
speeds, rightly, show nothing; what finds the forger then is the link check
(SAFETY 17): its counters interleave with the controller's, and its own
frames, however many, no longer pay back the errors that makes
(``E2EReceiver.min_decay_s``). The bus scenario's forger
(tests/hil/adversary.py, ``Adversary.walk``) starts on hearing a genuine
frame, as an attacker on the bus would, so that its burst moves the drive.
"""

from __future__ import annotations

from millctl.controller import ControllerState as S
from millctl.protocol import Decoded, FaultCode, ProtocolError, Setpoints
from tests.unit.scenarios.rig import Rig

LOW_RPM = (60.0, 300.0)
STEP_RPM = 8.0
"""How far past the last forged frame each forged frame asks ω_v to go (rpm)."""
FRAMES_PER_TICK = 10
"""Forged frames per node tick of 10 ms: 1000 a second."""
ATTACK_S = 0.3


def genuine_setpoints(rig: Rig) -> list[Decoded]:
    """The Setpoints frames the bystander heard since it last looked (all the controller's: nobody else sent)."""
    heard = []
    for frame in iter(lambda: rig.probe.recv(timeout=0.0), None):
        try:
            decoded = rig.codec.decode(frame)
        except ProtocolError:
            continue
        if isinstance(decoded.message, Setpoints):
            heard.append(decoded)
    return heard


def tick(rig: Rig) -> list[Decoded]:
    """One step of the node and the controller (without the rig's ``step``, which drains the bystander)."""
    rig.node.tick()
    rig.controller.tick()
    rig.clock.advance(rig.dt_s)
    return genuine_setpoints(rig)


def next_genuine(rig: Rig) -> tuple[int, float]:
    """Step until the controller sends its next Setpoints frame; its counter and when it went out (s)."""
    genuine_setpoints(rig)
    for _ in range(round(1.0 / rig.dt_s)):
        sent_s = rig.clock.now()
        if heard := tick(rig):
            assert heard[-1].counter is not None
            return heard[-1].counter, sent_s
    raise AssertionError("the controller sent no Setpoints frame in 1 s")


def attack(rig: Rig, counter: int, asked_rpm: float = LOW_RPM[1]) -> float:
    """The forger's frames from ``counter`` and ``asked_rpm`` + 8 rpm on, ``FRAMES_PER_TICK`` before each node tick,
    for ``ATTACK_S``; the measured ω_v peak (rpm)."""
    peak_rpm, top_rpm = 0.0, rig.config.drives.vibration.max_speed_rpm
    for _ in range(round(ATTACK_S / rig.dt_s)):
        for _ in range(FRAMES_PER_TICK):
            asked_rpm = min(asked_rpm + STEP_RPM, top_rpm)
            rig.probe.send(rig.codec.encode(Setpoints(LOW_RPM[0], asked_rpm, 25.0, False), counter))
            counter = (counter + 1) % 16
        tick(rig)
        peak_rpm = max(peak_rpm, rig.node.measured_speeds_rpm[1])
    return peak_rpm


def test_a_forger_that_starts_after_a_genuine_frame_moves_the_drive_and_the_controller_trips(rig: Rig) -> None:
    rig.start(*LOW_RPM)
    counter, _ = next_genuine(rig)
    peak_rpm = attack(rig, (counter + 1) % 16)
    tolerance = rig.config.interlock.measurement_tolerance_rpm
    assert peak_rpm > LOW_RPM[1] + tolerance
    assert rig.controller.state is S.TRIPPED
    assert "is not what was commanded" in rig.controller.trip_cause


def test_a_genuine_frame_fresh_by_chance_inside_the_burst_undoes_the_forgery_and_the_link_check_finds_the_forger(
    rig: Rig,
) -> None:
    """The forger's two frames just before the controller's next one carry counters 2 and 1 behind it: the first
    is out of sequence (refused, the receiver resynchronises on it), the second is taken (+16 rpm), and the
    controller's frame, one past it, is fresh and steps back inside what is left of the burst. The drive never
    moves past the tolerance, so the measured speeds show nothing; the interleaved counters fault the node's
    link all the same (SAFETY 17: the forger's own frames do not pay back the errors), and the controller trips
    on the node's fault."""
    rig.start(*LOW_RPM)
    counter, sent_s = next_genuine(rig)
    period_s = rig.config.timing.setpoint_period_s
    while rig.clock.now() < sent_s + period_s - rig.dt_s:  # the controller's next frame goes out in this tick
        tick(rig)
    for k, forged_counter in enumerate((counter - 1, counter), start=1):
        forged = Setpoints(LOW_RPM[0], LOW_RPM[1] + k * STEP_RPM, 25.0, False)
        rig.probe.send(rig.codec.encode(forged, forged_counter % 16))
    assert [frame.counter for frame in tick(rig)] == [(counter + 1) % 16]
    assert rig.node.last_setpoint == Setpoints(LOW_RPM[0], LOW_RPM[1] + 2 * STEP_RPM, 25.0, False)
    tick(rig)  # the node reads the controller's frame
    assert rig.node.last_setpoint == Setpoints(*LOW_RPM, 25.0, False)

    peak_rpm = attack(rig, (counter + 1) % 16, LOW_RPM[1] + 2 * STEP_RPM)
    assert peak_rpm < LOW_RPM[1] + rig.config.interlock.measurement_tolerance_rpm
    assert rig.node.first_fault is FaultCode.E2E_LINK
    assert rig.controller.state is S.TRIPPED
