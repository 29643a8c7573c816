"""The node's link safety (firmware_sim/link.py) on its own: E2E receivers, challenges, the heartbeat watchdog.

Frames are handed to :class:`LinkMonitor` as the codec would decode them, on
a clock the test sets: each rule is shown at its bound, without a bus.
"""

from __future__ import annotations

from firmware_sim.link import CHALLENGE_VALUES, GUARDED, ChallengeSequence, LinkMonitor
from millctl.config import MillConfig
from millctl.protocol import Command, CommandCode, ControllerState, Decoded, E2EStatus, Heartbeat, Setpoints

HEARTBEAT_ID = 0x010
"""Any identifier: the monitor judges a frame by its kind, counter and CRC."""


def heartbeat(counter: int, echo: int, *, crc_ok: bool = True) -> Decoded:
    message = Heartbeat(ControllerState.RUNNING, echo) if crc_ok else None
    return Decoded(Heartbeat, message, counter, crc_ok, HEARTBEAT_ID)


def test_every_guarded_message_has_its_own_receiver_with_the_configured_limits(config: MillConfig) -> None:
    link = LinkMonitor(config)
    interlock = config.interlock
    assert (Command, Heartbeat, Setpoints) == GUARDED
    assert set(link.receivers) == set(GUARDED)
    for kind, receiver in link.receivers.items():
        assert receiver.name == kind.__name__
        assert receiver.error_limit == interlock.e2e_error_limit
        assert receiver.sequence_decay_frames == interlock.e2e_sequence_decay_frames
        assert receiver.score == receiver.sequence_score == 0
    assert link.timeout_s == config.timing.watchdog_timeout_s
    assert link.lifetime_s == config.timing.challenge_lifetime_s
    assert (link.last_heartbeat_s, link.fresh_heartbeats, link.expired_echoes) == (None, 0, 0)
    assert not link.faulted


def test_no_heartbeat_yet_is_not_a_live_one(config: MillConfig) -> None:
    assert not LinkMonitor(config).heartbeat_live(0.0)


def test_a_fresh_heartbeat_keeps_the_watchdog_fed_until_its_timeout_inclusive(config: MillConfig) -> None:
    link = LinkMonitor(config)
    timeout_s = config.timing.watchdog_timeout_s
    challenge = link.issue_challenge(0.0)
    assert link.check(heartbeat(3, challenge), 0.0) is E2EStatus.OK
    assert link.last_heartbeat_s == 0.0
    assert link.heartbeat_live(0.0)
    assert link.heartbeat_live(timeout_s)  # at the bound: still live
    assert not link.heartbeat_live(timeout_s + 1e-6)


def test_each_fresh_heartbeat_and_each_stale_echo_is_counted_once(config: MillConfig) -> None:
    link = LinkMonitor(config)
    for i in range(3):  # three heartbeats, each echoing the challenge just issued
        now_s = 0.05 * i
        assert link.check(heartbeat(i, link.issue_challenge(now_s)), now_s) is E2EStatus.OK
        assert link.last_heartbeat_s == now_s
    assert (link.fresh_heartbeats, link.expired_echoes) == (3, 0)
    live = link.issue_challenge(0.15)
    stale = (live + 1) % 65536
    for i in range(3, 5):  # fresh counters whose echo is no live challenge
        assert link.check(heartbeat(i, stale), 0.2) is E2EStatus.OK
    assert (link.fresh_heartbeats, link.expired_echoes) == (3, 2)
    assert link.last_heartbeat_s == 0.1  # the stale echoes fed nothing


def test_a_heartbeat_that_is_not_fresh_by_its_counter_feeds_nothing_and_counts_nothing(config: MillConfig) -> None:
    link = LinkMonitor(config)
    challenge = link.issue_challenge(0.0)
    link.check(heartbeat(7, challenge), 0.0)
    assert link.check(heartbeat(7, challenge), 0.1) is E2EStatus.REPEATED
    assert link.check(heartbeat(8, challenge, crc_ok=False), 0.1) is E2EStatus.WRONG_CRC
    assert link.last_heartbeat_s == 0.0
    assert (link.fresh_heartbeats, link.expired_echoes) == (1, 0)


def test_a_command_frame_never_feeds_the_watchdog(config: MillConfig) -> None:
    link = LinkMonitor(config)
    command = Decoded(Command, Command(CommandCode.ARM), 0, True, 0x001)
    assert link.check(command, 0.0) is E2EStatus.OK
    assert link.last_heartbeat_s is None
    assert link.receivers[Command].last_counter == 0 and link.receivers[Heartbeat].last_counter is None


def test_bad_frames_on_one_guarded_message_fault_the_link_until_the_scores_are_cleared(config: MillConfig) -> None:
    link = LinkMonitor(config)
    limit = config.interlock.e2e_error_limit
    for i in range(limit):
        assert not link.faulted
        link.check(heartbeat(i, 0, crc_ok=False), 0.01 * i)
    assert link.faulted
    link.reset_scores()
    assert not link.faulted
    assert all(r.score == r.sequence_score == 0 for r in link.receivers.values())


def test_challenges_are_16_bit_and_only_the_live_ones_are_kept(config: MillConfig) -> None:
    link = LinkMonitor(config)
    period_s = 0.05  # one NodeStatus a tick
    values = [link.issue_challenge(i * period_s) for i in range(400)]
    assert all(0 <= v < 65536 for v in values)
    assert len(set(values)) == 400  # no value twice within 65 536 challenges
    kept = link._challenges  # what an hour of NodeStatus frames would otherwise pile up
    assert len(kept) == round(config.timing.challenge_lifetime_s / period_s) + 1
    assert [serial for serial, _, _ in kept] == list(range(400 - len(kept), 400))
    assert kept[-1][1] == values[-1]


def test_the_challenge_sequence_runs_through_every_16_bit_value_before_any_repeats() -> None:
    for sequence in (ChallengeSequence() for _ in range(3)):
        assert sequence.step % 2 == 1
        values = [sequence.value(k) for k in range(CHALLENGE_VALUES)]
        assert sorted(values) == list(range(CHALLENGE_VALUES))
        assert sequence.value(CHALLENGE_VALUES) == values[0]


def test_a_restarted_node_draws_a_new_sequence() -> None:
    runs = {tuple(ChallengeSequence().value(k) for k in range(4)) for _ in range(8)}
    assert len(runs) > 1  # 2³¹ start/step pairs: eight boots all alike would be one chance in about 2²¹⁷


def test_each_boot_steps_its_challenges_by_its_own_odd_step() -> None:
    """With one step for every boot, a later boot's sequence is an earlier one's shifted: once the later boot
    reaches the first recorded value, a recording from the earlier boot replayed in order echoes each new
    challenge as it is issued and feeds the watchdog. Each boot draws its own odd step, so the two fall
    apart after one match."""
    boots = [ChallengeSequence() for _ in range(8)]
    steps = [(boot.value(1) - boot.value(0)) % CHALLENGE_VALUES for boot in boots]
    assert all(step % 2 == 1 for step in steps)  # odd: a full cycle before any repeat
    assert len(set(steps)) > 1  # 2¹⁵ odd steps: eight boots on one step would be one chance in 2¹⁰⁵
    earlier, later = next((a, b) for a in boots for b in boots if a.step != b.step)
    recording = [earlier.value(k) for k in range(16)]
    shift = next(k for k in range(CHALLENGE_VALUES) if later.value(k) == recording[0])
    assert [later.value(shift + k) for k in range(16)] != recording  # in step for one frame at most


def test_a_replayed_echo_never_matches_a_newer_challenge_even_with_hundreds_live(config: MillConfig) -> None:
    """The vcan VM's failure: its scaled lifetime (10 s) keeps 200 challenges live, and a loop of 16 recorded
    heartbeats kept the watchdog fed for 11 s, as a random 16-bit challenge now and then equalled a recorded echo.

    Here a recording of 4000 heartbeats is replayed one per NodeStatus, 4000 times, after the controller
    died: drawn at random, about 4000 × 200 / 65 536 ≈ 12 echoes would match a live challenge.
    """
    timing = config.timing.model_copy(update={"challenge_lifetime_s": 10.0, "watchdog_timeout_s": 5.0})
    link = LinkMonitor(config.model_copy(update={"timing": timing}))
    period_s = 0.05  # NodeStatus at 20 Hz: 200 challenges live at once
    recording = 4000
    recorded = []
    for k in range(recording + 200):  # the controller echoes each challenge; the first 4000 heartbeats are recorded
        challenge = link.issue_challenge(k * period_s)
        assert link.echo_fresh(challenge, k * period_s)
        recorded.append(challenge)
    del recorded[recording:]  # the recording ages by 10 s, one lifetime, before the controller dies
    accepted = []
    for k, echo in enumerate(recorded, start=recording + 200):  # the node issues on; the replay echoes the recording
        link.issue_challenge(k * period_s)
        if link.echo_fresh(echo, k * period_s):
            accepted.append(echo)
    assert accepted == []


def test_an_echo_of_no_challenge_in_play_is_not_fresh(config: MillConfig) -> None:
    link = LinkMonitor(config)
    assert not link.echo_fresh(0, 0.0)  # nothing issued yet: not even the initial 0 counts
    challenge = link.issue_challenge(0.0)
    assert not link.echo_fresh((challenge + 1) % 65536, 0.01)  # every live challenge looked at, none matches
    assert link.echo_fresh(challenge, 0.02)


def test_a_challenge_is_live_for_its_lifetime_inclusive(config: MillConfig) -> None:
    lifetime_s = config.timing.challenge_lifetime_s
    link = LinkMonitor(config)
    challenge = link.issue_challenge(0.0)
    assert link.echo_fresh(challenge, lifetime_s)  # at the bound: still live
    link = LinkMonitor(config)
    challenge = link.issue_challenge(0.0)
    assert not link.echo_fresh(challenge, lifetime_s + 1e-6)
