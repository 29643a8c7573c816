"""The controller's view of the node's streams: freshness, staleness bounds, start-up grace, E2E health
(millctl/controller/tracking.py; docs/safety.md#stale-telemetry).

A stream is stale once its last fresh frame is older than max(stale_periods ×
its DBC period, min_stale_s); before its first frame it is judged from when
the node was first seen, with at least ``interlock.startup_grace_s``. The
interlock below makes every one of those terms decide some stream's bound.
"""

from __future__ import annotations

import can
import pytest

from millctl.config import MillConfig
from millctl.config.models import Interlock
from millctl.controller.tracking import SAFETY_RELEVANT, TelemetryTracker
from millctl.protocol import (
    ControllerState,
    Decoded,
    DriveTelemetry,
    FurnaceTelemetry,
    Heartbeat,
    MillMessage,
    NodeState,
    NodeStatus,
    PhysicsTelemetry,
    default_codec,
)

CODEC = default_codec()
SAMPLES: dict[type[MillMessage], MillMessage] = {
    NodeStatus: NodeStatus(NodeState.ARMED),
    DriveTelemetry: DriveTelemetry(10.0, 100.0, 0.5, 0.2),
    FurnaceTelemetry: FurnaceTelemetry(25.0, 25.0, 0.0, False),
    PhysicsTelemetry: PhysicsTelemetry(False, 10.0, 5.0, 1.0, 2.0),
}


@pytest.fixture
def interlock(config: MillConfig) -> Interlock:
    """stale_periods 10, min_stale_s 0.3, startup_grace_s 0.7: NodeStatus (50 ms) is stale after 0.5 s (its
    periods), DriveTelemetry (20 ms) after 0.3 s (the minimum), FurnaceTelemetry (100 ms) after 1.0 s; before
    their first frames NodeStatus and DriveTelemetry are given the grace (0.7 s), FurnaceTelemetry its 1.0 s."""
    return config.interlock.model_copy(
        update={"stale_periods": 10.0, "min_stale_s": 0.3, "startup_grace_s": 0.7, "e2e_error_limit": 3}
    )


BOUND_S = {NodeStatus: 0.5, DriveTelemetry: 0.3, FurnaceTelemetry: 1.0}
GRACE_S = {NodeStatus: 0.7, DriveTelemetry: 0.7, FurnaceTelemetry: 1.0}


def frame(kind: type[MillMessage], counter: int = 0, *, corrupt: bool = False) -> Decoded:
    """A node frame of ``kind`` as the controller decodes it (its CRC broken if ``corrupt``)."""
    encoded = CODEC.encode(SAMPLES[kind], counter)
    if corrupt:
        data = bytearray(encoded.data)
        data[0] ^= 0x01
        encoded = can.Message(arbitration_id=encoded.arbitration_id, data=bytes(data), is_extended_id=False)
    return CODEC.decode(encoded)


def feed_all(tracker: TelemetryTracker, now_s: float, counter: int = 0) -> None:
    for kind in SAMPLES:
        assert tracker.accept(frame(kind, counter), now_s) == SAMPLES[kind]


@pytest.mark.parametrize("kind", SAFETY_RELEVANT)
def test_a_stream_is_stale_just_past_its_bound_and_fresh_until_then(
    interlock: Interlock, kind: type[MillMessage]
) -> None:
    tracker = TelemetryTracker(CODEC, interlock)
    tracker.connected(0.0)
    feed_all(tracker, 0.0)
    others = [k for k in SAFETY_RELEVANT if k is not kind]
    for step in range(1, 200):  # keep the other streams fresh
        now = step * 0.01
        for other in others:
            tracker.accept(frame(other, step % 16), now)
        stale = tracker.stale(now)
        if now <= BOUND_S[kind] - 1e-9:
            assert stale == [], (now, stale)
        elif now > BOUND_S[kind] + 1e-9:
            assert len(stale) == 1 and stale[0].startswith(f"{kind.__name__} stale: age {now:.2f} s"), (now, stale)
            assert f"bound {BOUND_S[kind]:.2f} s" in stale[0]
            return
    raise AssertionError("never stale")


def test_a_fresh_frame_restarts_the_age_and_the_physics_stream_is_never_judged(interlock: Interlock) -> None:
    tracker = TelemetryTracker(CODEC, interlock)
    tracker.connected(0.0)
    feed_all(tracker, 0.0)
    for kind in SAFETY_RELEVANT:
        tracker.accept(frame(kind, 1), 0.25)
    assert tracker.stale(0.5) == []  # DriveTelemetry's 0.3 s counted from 0.25 s
    assert tracker.tracks[DriveTelemetry].age_s(0.5) == pytest.approx(0.25)
    for kind in SAFETY_RELEVANT:
        tracker.accept(frame(kind, 2), 10.0)
    assert tracker.stale(10.0) == []  # PhysicsTelemetry is 10 s old: informational only


def test_before_the_node_is_seen_nothing_is_stale(interlock: Interlock) -> None:
    tracker = TelemetryTracker(CODEC, interlock)
    assert tracker.stale(100.0) == []


@pytest.mark.parametrize("kind", SAFETY_RELEVANT)
def test_a_stream_never_received_is_stale_past_its_start_up_bound_from_when_the_node_was_seen(
    interlock: Interlock, kind: type[MillMessage]
) -> None:
    tracker = TelemetryTracker(CODEC, interlock)
    tracker.connected(5.0)
    tracker.connected(6.0)  # seen again: the start-up clock keeps its first instant
    others = [k for k in SAFETY_RELEVANT if k is not kind]
    for step in range(1, 200):
        now = 5.0 + step * 0.01
        for other in others:
            tracker.accept(frame(other, step % 16), now)
        stale = tracker.stale(now)
        if now - 5.0 <= GRACE_S[kind] - 1e-9:
            assert stale == [], (now, stale)
        elif now - 5.0 > GRACE_S[kind] + 1e-9:
            assert len(stale) == 1, (now, stale)
            assert stale[0].startswith(f"{kind.__name__} stale: never received in {now - 5.0:.2f} s")
            assert f"> bound {GRACE_S[kind]:.2f} s (interlock.startup_grace_s)" in stale[0]
            return
    raise AssertionError("never stale")


def test_a_frame_that_is_not_fresh_is_counted_but_not_taken(interlock: Interlock) -> None:
    tracker = TelemetryTracker(CODEC, interlock)
    assert tracker.accept(frame(DriveTelemetry, 4), 1.0) == SAMPLES[DriveTelemetry]
    assert tracker.accept(frame(DriveTelemetry, 4), 1.2) is None  # a repeated counter
    assert tracker.accept(frame(DriveTelemetry, 5, corrupt=True), 1.3) is None
    track = tracker.tracks[DriveTelemetry]
    assert track.received_s == 1.0 and track.frames == 1
    assert track.counts == {"ok": 1, "repeated": 1, "wrong-crc": 1}
    assert track.last == SAMPLES[DriveTelemetry]


def test_a_frame_of_a_kind_the_node_does_not_send_is_ignored(interlock: Interlock) -> None:
    tracker = TelemetryTracker(CODEC, interlock)
    heartbeat = CODEC.decode(CODEC.encode(Heartbeat(ControllerState.RUNNING, 0), 0))
    assert tracker.accept(heartbeat, 1.0) is None
    assert Heartbeat not in tracker.tracks


def test_e2e_errors_up_to_the_limit_fault_that_link_until_the_links_are_reset(interlock: Interlock) -> None:
    tracker = TelemetryTracker(CODEC, interlock)
    feed_all(tracker, 0.0, counter=3)
    for i in range(interlock.e2e_error_limit - 1):
        tracker.accept(frame(FurnaceTelemetry, 4 + i, corrupt=True), 0.1)
    assert tracker.link_faults() == []
    tracker.accept(frame(FurnaceTelemetry, 9, corrupt=True), 0.1)
    faults = tracker.link_faults()
    assert len(faults) == 1 and faults[0].startswith("FurnaceTelemetry E2E error score 3 ≥ limit 3"), faults
    tracker.reset_links()
    assert tracker.link_faults() == []
    assert tracker.accept(frame(NodeStatus, 3), 0.2) == SAMPLES[NodeStatus]  # the last counter is forgotten too


def test_the_health_of_each_stream_for_the_status_display(interlock: Interlock) -> None:
    tracker = TelemetryTracker(CODEC, interlock)
    before = tracker.health(0.0)
    assert set(before) == {"NodeStatus", "DriveTelemetry", "FurnaceTelemetry", "PhysicsTelemetry"}
    assert before["NodeStatus"] == {
        "age_s": None,
        "stale_after_s": 0.5,
        "stale": True,
        "frames": 0,
        "e2e": {},
        "e2e_score": 0,
        "e2e_sequence_score": 0,
    }
    feed_all(tracker, 1.0, counter=7)
    tracker.accept(frame(DriveTelemetry, 7), 1.1)  # a repeated counter: a sequence error
    tracker.accept(frame(DriveTelemetry, 8, corrupt=True), 1.1)
    health = tracker.health(1.25)
    assert health["DriveTelemetry"] == {
        "age_s": pytest.approx(0.25),
        "stale_after_s": 0.3,
        "stale": False,
        "frames": 1,
        "e2e": {"ok": 1, "repeated": 1, "wrong-crc": 1},
        "e2e_score": 2,
        "e2e_sequence_score": 1,
    }
    assert health["NodeStatus"]["stale"] is False
    assert health["PhysicsTelemetry"]["e2e"] == {"ok": 1}  # not protected: every frame counts as ok
    physics = health["PhysicsTelemetry"]
    assert (physics["e2e_score"], physics["e2e_sequence_score"], physics["stale_after_s"]) == (0, 0, 1.0)
    assert tracker.health(1.5)["NodeStatus"]["stale"] is False  # exactly its bound old: not yet stale
    assert tracker.health(1.31)["DriveTelemetry"]["stale"] is True


def test_a_stream_exactly_its_bound_old_is_not_yet_stale(interlock: Interlock) -> None:
    tracker = TelemetryTracker(CODEC, interlock)
    tracker.connected(0.0)
    tracker.accept(frame(NodeStatus, 0), 0.0)
    tracker.accept(frame(DriveTelemetry, 0), 0.5)
    assert tracker.stale(0.5) == []  # NodeStatus 0.5 s old, its bound; FurnaceTelemetry never received, 0.5 s
    tracker.accept(frame(NodeStatus, 1), 0.5)
    tracker.accept(frame(DriveTelemetry, 1), 1.0)
    assert tracker.stale(1.0) == []  # FurnaceTelemetry never received, 1.0 s: its start-up bound
    assert len(tracker.stale(1.0 + 1e-6)) == 2  # now NodeStatus and FurnaceTelemetry


def test_each_fresh_frame_and_each_e2e_verdict_is_counted_for_the_status_display(interlock: Interlock) -> None:
    tracker = TelemetryTracker(CODEC, interlock)
    for counter in (1, 2, 3):
        tracker.accept(frame(NodeStatus, counter), 0.1 * counter)
    tracker.accept(frame(NodeStatus, 3), 0.4)  # repeated
    tracker.accept(frame(NodeStatus, 3), 0.45)  # repeated again
    health = tracker.health(0.5)["NodeStatus"]
    assert (health["frames"], health["e2e"]) == (3, {"ok": 3, "repeated": 2})


def test_the_configured_sequence_decay_is_the_links_own(interlock: Interlock) -> None:
    """interlock.e2e_sequence_decay_frames: a repeated counter is forgiven after that many fresh frames."""
    tracker = TelemetryTracker(CODEC, interlock.model_copy(update={"e2e_sequence_decay_frames": 2}))
    tracker.accept(frame(DriveTelemetry, 1), 0.0)
    tracker.accept(frame(DriveTelemetry, 1), 0.02)  # repeated: a sequence point
    assert tracker.health(0.02)["DriveTelemetry"]["e2e_sequence_score"] == 1
    tracker.accept(frame(DriveTelemetry, 2), 0.04)
    assert tracker.health(0.04)["DriveTelemetry"]["e2e_sequence_score"] == 1
    tracker.accept(frame(DriveTelemetry, 3), 0.06)  # the second fresh frame since: forgiven
    assert tracker.health(0.06)["DriveTelemetry"]["e2e_sequence_score"] == 0
