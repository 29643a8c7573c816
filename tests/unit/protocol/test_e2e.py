"""E2E protection: CRC known answers, the alive counter, and the receiver-side checker."""

from __future__ import annotations

import pytest
from crccheck.crc import Crc8SaeJ1850
from hypothesis import example, given
from hypothesis import strategies as st

from millctl.config import MillConfig
from millctl.protocol import AliveCounter, E2EReceiver, E2EStatus, crc8_sae_j1850, e2e_crc, sequence_decay_s

# AUTOSAR SWS CRC Library, CRC8 (SAE J1850) examples, and the CRC catalogue's check value.
KNOWN_ANSWERS = [
    ("00000000", 0x59),
    ("F20183", 0x37),
    ("0FAA0055", 0x79),
    ("00FF5511", 0xB8),
    ("332255AABBCCDDEEFF", 0xCB),
    ("926B55", 0x8C),
    ("FFFFFFFF", 0x74),
    ("313233343536373839", 0x4B),  # b"123456789"
]


@pytest.mark.parametrize(("hex_data", "expected"), KNOWN_ANSWERS)
def test_crc8_sae_j1850_known_answers(hex_data: str, expected: int) -> None:
    assert crc8_sae_j1850(bytes.fromhex(hex_data)) == expected


@given(st.binary(max_size=64))
@example(b"")  # no bytes: the CRC is init XOR xorout
@example(b"\x00" * 64)
@example(b"\xff" * 64)
def test_crc8_sae_j1850_agrees_with_an_independent_implementation(data: bytes) -> None:
    """crccheck's table-free CRC-8/SAE-J1850 (poly 0x1D, init 0xFF, xorout 0xFF) is the oracle."""
    assert crc8_sae_j1850(data) == Crc8SaeJ1850.calc(data)


@given(st.integers(0, 0xFFFF), st.binary(min_size=1, max_size=7))
def test_e2e_crc_covers_data_id_low_then_high_then_payload(data_id: int, payload: bytes) -> None:
    """AUTOSAR E2E: the CRC runs over the data ID's low byte, its high byte, then the payload (oracle: crccheck)."""
    low, high = data_id.to_bytes(2, "little")
    assert e2e_crc(data_id, payload) == Crc8SaeJ1850.calc(bytes((low, high)) + payload)


def test_e2e_crc_known_answer_and_sensitivity() -> None:
    payload = bytes.fromhex("05A00FE02E1C25")
    # crccheck: Crc8SaeJ1850.calc(bytes.fromhex("304D05A00FE02E1C25")) == 0xC3
    assert e2e_crc(0x4D30, payload) == 0xC3
    assert e2e_crc(0x4D30, payload) != e2e_crc(0x4D20, payload)
    assert e2e_crc(0x304D, payload) != e2e_crc(0x4D30, payload)
    with pytest.raises(ValueError, match="data ID"):
        e2e_crc(0x1_0000, payload)


def test_alive_counter_wraps_after_15() -> None:
    counter = AliveCounter(start=14)
    assert [counter.next() for _ in range(4)] == [14, 15, 0, 1]
    assert counter.value == 2
    with pytest.raises(ValueError):
        AliveCounter(start=16)


def classify_all(receiver: E2EReceiver, counters: list[int | None]) -> list[E2EStatus]:
    return [receiver.classify(c, crc_ok=c is not None) for c in counters]


def test_in_sequence_and_wrap_around_are_ok() -> None:
    receiver = E2EReceiver(error_limit=5)
    statuses = classify_all(receiver, [12, 13, 14, 15, 0, 1, 2])
    assert statuses == [E2EStatus.OK] * 7
    assert receiver.score == 0


def test_loss_within_max_delta_is_fresh_but_larger_jump_is_not() -> None:
    receiver = E2EReceiver(error_limit=5, max_delta=3)
    assert classify_all(receiver, [14, 1, 4]) == [E2EStatus.OK, E2EStatus.OK_SOME_LOST, E2EStatus.OK_SOME_LOST]
    status = receiver.classify(9, crc_ok=True)
    assert status is E2EStatus.WRONG_SEQUENCE
    assert not status.fresh
    # The receiver resynchronises on the new counter: the next one in sequence is fresh again.
    assert receiver.classify(10, crc_ok=True) is E2EStatus.OK


def test_repetition_and_going_back_never_count_as_fresh() -> None:
    receiver = E2EReceiver(error_limit=5)
    statuses = classify_all(receiver, [3, 3, 3, 2])
    assert statuses[0] is E2EStatus.OK
    assert statuses[1:3] == [E2EStatus.REPEATED, E2EStatus.REPEATED]
    assert statuses[3] is E2EStatus.WRONG_SEQUENCE  # 3 -> 2 is a step of 15
    assert [s.fresh for s in statuses] == [True, False, False, False]


def test_corruption_is_wrong_crc_and_does_not_move_the_counter() -> None:
    receiver = E2EReceiver(error_limit=5)
    assert receiver.classify(7, crc_ok=True) is E2EStatus.OK
    assert receiver.classify(8, crc_ok=False) is E2EStatus.WRONG_CRC
    assert receiver.classify(8, crc_ok=True) is E2EStatus.OK
    assert receiver.counts[E2EStatus.WRONG_CRC] == 1


def test_net_error_score_faults_the_link_at_the_configured_limit_and_recovers(config: MillConfig) -> None:
    limit = config.interlock.e2e_error_limit
    receiver = E2EReceiver(error_limit=limit)
    receiver.classify(0, crc_ok=True)
    for _ in range(limit - 1):
        receiver.classify(None, crc_ok=False)
    assert receiver.score == limit - 1
    assert not receiver.faulted
    receiver.classify(0, crc_ok=True)  # repeated: an error too
    assert receiver.faulted
    receiver.classify(1, crc_ok=True)
    assert not receiver.faulted
    for counter in range(2, 2 + limit):
        receiver.classify(counter, crc_ok=True)
    assert receiver.score == 0


def test_alternating_errors_and_good_frames_do_not_accumulate() -> None:
    receiver = E2EReceiver(error_limit=3)
    counter = AliveCounter()
    for _ in range(50):
        receiver.classify(counter.next(), crc_ok=True)
        receiver.classify(None, crc_ok=False)
    assert not receiver.faulted


def test_receiver_rejects_nonsense_limits() -> None:
    with pytest.raises(ValueError):
        E2EReceiver(error_limit=0)
    with pytest.raises(ValueError):
        E2EReceiver(error_limit=5, max_delta=15)
    with pytest.raises(ValueError):
        E2EReceiver(error_limit=5, max_delta=0)


def test_a_receiver_that_allows_no_lost_frame_takes_only_the_next_counter() -> None:
    receiver = E2EReceiver(error_limit=5, max_delta=1)
    assert receiver.classify(3, crc_ok=True) is E2EStatus.OK
    assert receiver.classify(4, crc_ok=True) is E2EStatus.OK
    assert receiver.classify(6, crc_ok=True) is E2EStatus.WRONG_SEQUENCE
    assert E2EReceiver(error_limit=5, max_delta=14).max_delta == 14  # the largest a 4-bit counter can tell


def test_a_new_alive_counter_starts_at_zero() -> None:
    counter = AliveCounter()
    assert counter.value == 0
    assert [counter.next() for _ in range(17)] == [*range(16), 0]


def test_a_second_sender_answering_each_frame_with_counter_plus_one_faults_the_link() -> None:
    """SAFETY 17: genuine c, spoof c + 1 (OK), genuine c + 1 (REPEATED) … used to keep the net score level."""
    receiver = E2EReceiver(error_limit=5)
    genuine = AliveCounter()
    statuses = []
    for _ in range(8):
        counter = genuine.next()
        statuses += [receiver.classify(counter, crc_ok=True), receiver.classify((counter + 1) % 16, crc_ok=True)]
    assert receiver.score <= 1  # the net score alone stays level: the attack it could not see
    assert receiver.faulted and receiver.sequence_score >= 5
    reason = receiver.fault_reason()
    assert reason is not None and "second sender" in reason and "≥ limit 5" in reason
    assert statuses.count(E2EStatus.OK) >= 7  # every spoof was fresh: exactly why OK must not pay for REPEATED


def test_interleaved_senders_on_one_identifier_fault_the_link() -> None:
    receiver = E2EReceiver(error_limit=5)
    genuine, other = AliveCounter(), AliveCounter(start=8)
    for _ in range(10):
        receiver.classify(genuine.next(), crc_ok=True)
        receiver.classify(other.next(), crc_ok=True)
    assert receiver.faulted and receiver.sequence_score >= 5


def test_a_second_sender_slower_than_the_decay_is_forgiven_and_a_faster_one_is_not() -> None:
    decay = 16
    for every, faults in ((decay + 2, False), (decay - 4, True)):
        receiver = E2EReceiver(error_limit=5, sequence_decay_frames=decay)
        counter = AliveCounter()
        for i in range(40 * every):
            value = counter.next()
            receiver.classify(value, crc_ok=True)
            if i % every == every - 1:
                receiver.classify(value, crc_ok=True)  # one duplicate now and then
        assert receiver.faulted is faults, (every, receiver.sequence_score)


def test_the_least_decay_time_is_the_decay_frames_at_twice_the_senders_rate() -> None:
    assert sequence_decay_s(16, 0.1) == pytest.approx(0.8)  # 16 Setpoints frames at 20 Hz instead of 10
    assert sequence_decay_s(16, 0.02) == pytest.approx(0.16)  # 16 DriveTelemetry frames at 100 Hz instead of 50
    with pytest.raises(ValueError, match=r"the sender's period 0.0 s must be > 0"):
        sequence_decay_s(16, 0.0)


def forged_and_genuine(seconds: float, genuine_hz: float, forged_hz: float) -> list[tuple[float, int]]:
    """(arrival time s, counter) of a genuine sender and a forger that keeps its own counters, merged in time."""
    genuine, forger = AliveCounter(), AliveCounter(start=9)
    frames = [(k / genuine_hz, genuine.next()) for k in range(round(seconds * genuine_hz))]
    frames += [(k / forged_hz + 1e-4, forger.next()) for k in range(round(seconds * forged_hz))]
    return sorted(frames)


def test_a_forger_out_sending_the_genuine_sender_cannot_pay_back_the_errors_its_interleaving_makes() -> None:
    """SAFETY 17: a 1000 Hz forger beside a 10 Hz sender. Counted in frames alone, its own fresh frames forgave
    every error within the next 32 of them, and the link never faulted; with the sender's own pace as the
    least decay time it faults within a second."""
    frames = forged_and_genuine(5.0, genuine_hz=10.0, forged_hz=1000.0)
    frames_alone = E2EReceiver(error_limit=5)
    for t_s, counter in frames:
        frames_alone.classify(counter, crc_ok=True, now_s=t_s)
    assert not frames_alone.faulted and frames_alone.counts[E2EStatus.WRONG_SEQUENCE] >= 50
    paced = E2EReceiver(error_limit=5, min_decay_s=sequence_decay_s(16, 0.1))
    faulted_at = None
    for t_s, counter in frames:
        paced.classify(counter, crc_ok=True, now_s=t_s)
        if paced.faulted:
            faulted_at = t_s
            break
    assert faulted_at is not None and faulted_at < 1.0
    reason = paced.fault_reason()
    assert reason is not None and "second sender" in reason


@pytest.mark.parametrize(
    ("period_s", "forgiven_after"),
    [(0.1, 16), (0.05, 16), (0.025, 32)],  # its own rate, twice it (the slack), four times it
)
def test_a_sender_at_up_to_twice_its_rate_is_forgiven_at_the_frames_pace(period_s: float, forgiven_after: int) -> None:
    receiver = E2EReceiver(error_limit=5, min_decay_s=sequence_decay_s(16, 0.1))
    counter = AliveCounter()
    first = counter.next()
    receiver.classify(first, True, 0.0)
    receiver.classify(first, True, 0.0)  # one duplicate
    assert receiver.sequence_score == 1
    for k in range(1, 40):
        receiver.classify(counter.next(), True, k * period_s)
        if receiver.sequence_score == 0:
            break
    assert k == forgiven_after


def test_a_receiver_with_a_least_decay_time_needs_the_time_of_each_frame() -> None:
    receiver = E2EReceiver(error_limit=5, name="Setpoints", min_decay_s=0.8)
    with pytest.raises(ValueError, match=r"Setpoints: min_decay_s is set, so classify needs the time"):
        receiver.classify(0, crc_ok=True)
    with pytest.raises(ValueError, match=r"E2E min_decay_s -1.0 s must be finite and ≥ 0"):
        E2EReceiver(error_limit=5, min_decay_s=-1.0)
    with pytest.raises(ValueError, match=r"E2E min_decay_s inf s must be finite and ≥ 0"):
        E2EReceiver(error_limit=5, min_decay_s=float("inf"))


def test_sequence_score_decays_one_per_decay_frames_fresh_frames_and_clears_on_reset() -> None:
    receiver = E2EReceiver(error_limit=3, sequence_decay_frames=4)
    classify_all(receiver, [0, 0, 0, 0])  # three repeats
    assert receiver.sequence_score == 3 and receiver.faulted
    classify_all(receiver, [1, 2, 3])
    assert receiver.sequence_score == 3
    classify_all(receiver, [4])
    assert receiver.sequence_score == 2 and not receiver.faulted
    receiver.classify(4, crc_ok=True)
    receiver.clear_scores()
    assert (receiver.score, receiver.sequence_score, receiver.last_counter) == (0, 0, 4)
    with pytest.raises(ValueError, match="sequence_decay_frames 0"):
        E2EReceiver(error_limit=5, sequence_decay_frames=0)


def test_every_refused_parameter_is_named_with_its_value_and_range() -> None:
    with pytest.raises(ValueError, match=r"alive counter start 16 is outside 0 … 15"):
        AliveCounter(start=16)
    with pytest.raises(ValueError, match=r"alive counter start -1 is outside 0 … 15"):
        AliveCounter(start=-1)
    assert AliveCounter(start=15).value == 15 and AliveCounter(start=0).value == 0
    with pytest.raises(ValueError, match=r"E2E error limit 0 must be ≥ 1"):
        E2EReceiver(error_limit=0)
    with pytest.raises(ValueError, match=r"E2E max_delta 15 must be in 1 … 14"):
        E2EReceiver(error_limit=5, max_delta=15)
    with pytest.raises(ValueError, match=r"E2E max_delta 0 must be in 1 … 14"):
        E2EReceiver(error_limit=5, max_delta=0)
    assert E2EReceiver(error_limit=1, max_delta=14, sequence_decay_frames=1).max_delta == 14
    with pytest.raises(ValueError, match=r"E2E data ID -1 is outside 0 … 65535"):
        e2e_crc(-1, b"\x00")
    assert e2e_crc(0xFFFF, b"\x00") == Crc8SaeJ1850.calc(b"\xff\xff\x00")


def test_the_crc_parameters_can_be_given() -> None:
    """Start value and final XOR are parameters (0x00/0x00 is the plain CRC-8 with poly 0x1D)."""
    data = b"123456789"
    assert crc8_sae_j1850(data, start=0xFF, xor_out=0x00) == 0x4B ^ 0xFF
    assert crc8_sae_j1850(data, start=0x00, xor_out=0x00) == 0x37  # CRC-8/GSM-A's check value (poly 0x1D, init 0)
    assert crc8_sae_j1850(b"") == 0x00  # 0xFF, then the final XOR


def test_the_error_score_names_its_receiver_value_and_limit() -> None:
    receiver = E2EReceiver(error_limit=2, name="Heartbeat")
    receiver.classify(None, crc_ok=False)
    assert not receiver.faulted and receiver.fault_reason() is None
    receiver.classify(None, crc_ok=False)
    assert receiver.faulted
    assert receiver.fault_reason() == "Heartbeat E2E error score 2 ≥ limit 2"
    unnamed = E2EReceiver(error_limit=1)
    unnamed.classify(3, crc_ok=True)
    unnamed.classify(3, crc_ok=True)
    assert unnamed.fault_reason() == (
        "E2E link E2E sequence score 1 ≥ limit 1: repeated or out-of-sequence counters with good CRCs "
        "(a second sender or a replay on the identifier)"
    )


def test_a_counter_outside_four_bits_is_a_wrong_crc_and_counted() -> None:
    receiver = E2EReceiver(error_limit=5)
    assert receiver.classify(16, crc_ok=True) is E2EStatus.WRONG_CRC
    assert receiver.classify(-1, crc_ok=True) is E2EStatus.WRONG_CRC
    assert receiver.classify(None, crc_ok=True) is E2EStatus.WRONG_CRC
    assert receiver.last_counter is None and receiver.score == 3 and receiver.sequence_score == 0
    assert receiver.classify(15, crc_ok=True) is E2EStatus.OK
    assert receiver.counts == {
        E2EStatus.OK: 1,
        E2EStatus.OK_SOME_LOST: 0,
        E2EStatus.REPEATED: 0,
        E2EStatus.WRONG_SEQUENCE: 0,
        E2EStatus.WRONG_CRC: 3,
    }


def test_a_repeated_counter_does_not_move_the_last_counter_but_a_jump_resynchronises() -> None:
    receiver = E2EReceiver(error_limit=9, max_delta=2)
    assert classify_all(receiver, [5, 5, 7, 10, 11]) == [
        E2EStatus.OK,
        E2EStatus.REPEATED,
        E2EStatus.OK_SOME_LOST,  # 5 → 7: the largest step still "some lost"
        E2EStatus.WRONG_SEQUENCE,  # 7 → 10: one more
        E2EStatus.OK,
    ]
    assert receiver.last_counter == 11
    assert (receiver.score, receiver.sequence_score) == (1, 2)  # +1 +1 (errors) −1 (the last OK) from 1 … 0 floor


def test_some_lost_frames_neither_add_to_nor_pay_off_the_net_score() -> None:
    receiver = E2EReceiver(error_limit=9)
    classify_all(receiver, [0, None, None])
    assert receiver.score == 2
    assert receiver.classify(3, crc_ok=True) is E2EStatus.OK_SOME_LOST
    assert receiver.score == 2
    assert receiver.classify(4, crc_ok=True) is E2EStatus.OK
    assert receiver.score == 1


def test_the_sequence_score_decays_on_fresh_frames_counting_some_lost_ones() -> None:
    receiver = E2EReceiver(error_limit=9, sequence_decay_frames=2)
    classify_all(receiver, [0, 0, 0])
    assert receiver.sequence_score == 2
    classify_all(receiver, [2, 4])  # two "some lost": fresh, so they count toward a decay
    assert receiver.sequence_score == 1
    classify_all(receiver, [5])
    receiver.classify(5, crc_ok=True)  # a repeat restarts the run: 5 is not the second fresh frame of a pair
    classify_all(receiver, [6])
    assert receiver.sequence_score == 2
    classify_all(receiver, [7, 8, 9, 10, 11, 12])
    assert receiver.sequence_score == 0
    classify_all(receiver, [13, 14, 15])  # nothing to decay: the run does not build up in advance
    receiver.classify(15, crc_ok=True)
    assert receiver.sequence_score == 1
    classify_all(receiver, [0])
    assert receiver.sequence_score == 1


def test_check_reads_a_decoded_frames_counter_and_crc_verdict() -> None:
    class Frame:
        def __init__(self, counter: int | None, crc_ok: bool) -> None:
            self.counter, self.crc_ok = counter, crc_ok

    receiver = E2EReceiver(error_limit=5)
    assert receiver.check(Frame(4, True)) is E2EStatus.OK
    assert receiver.check(Frame(5, False)) is E2EStatus.WRONG_CRC
    assert receiver.check(Frame(5, True)) is E2EStatus.OK


def test_reset_forgets_the_counter_and_both_scores() -> None:
    receiver = E2EReceiver(error_limit=9)
    classify_all(receiver, [4, 4, None])
    assert (receiver.score, receiver.sequence_score, receiver.last_counter) == (2, 1, 4)
    receiver.reset()
    assert (receiver.score, receiver.sequence_score, receiver.last_counter) == (0, 0, None)
    assert receiver.classify(9, crc_ok=True) is E2EStatus.OK  # any counter is the first after a reset


def test_the_status_predicates() -> None:
    assert {s for s in E2EStatus if s.fresh} == {E2EStatus.OK, E2EStatus.OK_SOME_LOST}
    assert {s for s in E2EStatus if s.is_error} == {E2EStatus.REPEATED, E2EStatus.WRONG_SEQUENCE, E2EStatus.WRONG_CRC}
    assert {s for s in E2EStatus if s.is_sequence_error} == {E2EStatus.REPEATED, E2EStatus.WRONG_SEQUENCE}
