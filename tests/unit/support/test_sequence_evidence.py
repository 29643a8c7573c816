"""When the frames on the bus complete a second sender's evidence (tests/hil/scenario_support.py).

The hil test of a second sender times the controller's trip from that moment, so an error here would
stretch or shrink the bound it checks. The sequences are written out by hand, each with its answer.
"""

from __future__ import annotations

from collections.abc import Sequence

import can

from millctl.protocol import Decoded, DriveTelemetry
from tests.hil.scenario_support import Seen, sequence_limit_reached_at

TELEMETRY = DriveTelemetry(60.0, 300.0, 0.1, 0.1)


def frames(
    counters: Sequence[int | None], crc_bad: frozenset[int] = frozenset(), stamps: Sequence[float] | None = None
) -> list[Seen]:
    """One DriveTelemetry frame per counter, in the order received; the i-th stamped ``stamps[i]`` (default i s).

    None as a counter: a frame with no counter.
    """
    seen = []
    for i, counter in enumerate(counters):
        ok = i not in crc_bad
        decoded = Decoded(DriveTelemetry, TELEMETRY if ok else None, counter, ok, 0x110)
        t = float(i) if stamps is None else stamps[i]
        seen.append(Seen(t, can.Message(arbitration_id=0x110), decoded))
    return seen


def test_a_forger_answering_every_frame_with_counter_plus_one_completes_the_evidence_at_the_limitth_repeat() -> None:
    # genuine 0, forged 1, genuine 1 (repeated: 1), forged 2, genuine 2 (2), … genuine 5 (5) is frame 10
    counters = [0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6]
    assert sequence_limit_reached_at(frames(counters), limit=5, decay_frames=16) == 10.0
    assert sequence_limit_reached_at(frames(counters), limit=1, decay_frames=16) == 2.0


def test_one_sender_wrapping_and_losing_up_to_two_frames_gives_no_evidence() -> None:
    counters = [14, 15, 0, 1, 3, 6, 7, 8]  # steps of 1, 2 and 3 are fresh (some frames lost)
    assert sequence_limit_reached_at(frames(counters), limit=1, decay_frames=16) is None


def test_a_jump_past_three_counts_and_resynchronises() -> None:
    # 0 → 5 is out of sequence (1) and the receiver takes 5; 6 is then fresh; 6 → 11 is the second
    assert sequence_limit_reached_at(frames([0, 5, 6, 11]), limit=2, decay_frames=16) == 3.0
    assert sequence_limit_reached_at(frames([0, 5, 6, 7]), limit=2, decay_frames=16) is None


def test_a_repeat_does_not_move_the_counter_it_is_judged_against() -> None:
    # 3, 3 (repeat: 1), 4 is fresh against 3; had the repeat moved it, 4 would still be fresh: so 3, 3, 3
    assert sequence_limit_reached_at(frames([3, 3, 3]), limit=2, decay_frames=16) == 2.0
    assert sequence_limit_reached_at(frames([3, 4, 4, 5]), limit=2, decay_frames=16) is None


def test_the_score_decays_only_after_a_run_of_fresh_frames_as_long_as_the_decay() -> None:
    fifteen = [(1 + k) % 16 for k in range(15)]  # 1 … 15 after a repeated 0
    sixteen = [(1 + k) % 16 for k in range(16)]  # 1 … 15, 0
    forgiven = [0, 0, *sixteen, sixteen[-1]]  # a repeat, 16 fresh (score back to 0), a repeat: 1
    kept = [0, 0, *fifteen, fifteen[-1]]  # a repeat, 15 fresh, a repeat: 2
    assert sequence_limit_reached_at(frames(forgiven), limit=2, decay_frames=16) is None
    assert sequence_limit_reached_at(frames(kept), limit=2, decay_frames=16) == float(len(kept) - 1)


def test_the_score_decays_no_faster_than_the_controllers_least_decay_time() -> None:
    """The 16 fresh frames that forgive a repeat came 0.01 s apart: a sender five times its 0.05 s pace, whose run
    the controller (min_decay_s = 16 × 0.05 s / 2 = 0.4 s) has not forgiven when the next repeat comes."""
    sixteen = [(1 + k) % 16 for k in range(16)]
    counters = [0, 0, *sixteen, sixteen[-1]]
    stamps = [0.0, 0.0] + [0.01 * (k + 1) for k in range(16)] + [0.17]
    assert sequence_limit_reached_at(frames(counters, stamps=stamps), limit=2, decay_frames=16) is None
    assert sequence_limit_reached_at(frames(counters, stamps=stamps), limit=2, decay_frames=16, min_decay_s=0.4) == 0.17
    slow = [0.0, 0.0] + [0.05 * (k + 1) for k in range(16)] + [0.85]  # at its pace: 0.8 s ≥ 0.4 s, forgiven
    assert sequence_limit_reached_at(frames(counters, stamps=slow), limit=2, decay_frames=16, min_decay_s=0.4) is None


def test_frames_failing_their_crc_or_without_a_counter_are_not_judged() -> None:
    counters: list[int | None] = [0, 0, None, 1, 1]
    # frame 1 fails its CRC (a corruption, not a second sender), frame 2 has no counter: only frame 4 repeats
    assert sequence_limit_reached_at(frames(counters, crc_bad=frozenset({1})), limit=1, decay_frames=16) == 4.0
    assert sequence_limit_reached_at(frames(counters, crc_bad=frozenset({1})), limit=2, decay_frames=16) is None


def test_frames_received_out_of_the_order_they_were_sent_are_judged_as_sent() -> None:
    # The VM's capture: forged 1 (t 1), then forged 2 (t 3) received before genuine 1 (t 2), genuine 2, forged 3,
    # genuine 3. As received, genuine 1 goes back (out of sequence: 1) and the receiver resynchronises on it, so
    # genuine 2 looks fresh; the repeat of 3 is the second. As sent (0 1 1 2 2 3 3): repeats at t 2, 4 and 6.
    counters = [0, 1, 2, 1, 2, 3, 3]
    stamps = [0.0, 1.0, 3.0, 2.0, 4.0, 5.0, 6.0]
    assert sequence_limit_reached_at(frames(counters, stamps=stamps), limit=2, decay_frames=16) == 4.0
    assert sequence_limit_reached_at(frames(counters, stamps=stamps), limit=3, decay_frames=16) == 6.0


def test_frames_sent_in_sequence_but_received_out_of_it_count_as_received() -> None:
    # sent 0 1 2 3, received 0 2 1 3: as sent there is no error; as received, 1 after 2 goes back (out of sequence)
    counters = [0, 2, 1, 3]
    stamps = [0.0, 2.0, 1.0, 3.0]
    assert sequence_limit_reached_at(frames(counters, stamps=stamps), limit=1, decay_frames=16) == 1.0
    assert sequence_limit_reached_at(frames(counters, stamps=stamps), limit=2, decay_frames=16) is None
