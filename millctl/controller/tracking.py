"""Tracking the node's frames: the last message of each kind, its age, and its E2E health.

A node frame older than its bound — max(stale_periods × its DBC period,
min_stale_s) — is stale, and stale telemetry trips the controller
(docs/safety.md#stale-telemetry). At start-up the node's streams begin at
their own phases: a stream not yet received is judged from the moment the
node was first seen, with the bound max(its stale bound,
``interlock.startup_grace_s``), so that a start never trips on a stream that
is merely late, while one that never comes is still a fault. A stream's E2E
sequence score is forgiven no faster than the node sends it (its DBC period,
:func:`~millctl.protocol.e2e.sequence_decay_s`; SAFETY 17).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from millctl.config.models import Interlock
from millctl.protocol import (
    Codec,
    Decoded,
    DriveTelemetry,
    E2EReceiver,
    E2EStatus,
    FurnaceTelemetry,
    MillMessage,
    NodeStatus,
    PhysicsTelemetry,
    sequence_decay_s,
)

TRACKED: tuple[type[MillMessage], ...] = (NodeStatus, DriveTelemetry, FurnaceTelemetry, PhysicsTelemetry)
"""The node's periodic frames the controller follows."""

SAFETY_RELEVANT: tuple[type[MillMessage], ...] = (NodeStatus, DriveTelemetry, FurnaceTelemetry)
"""Those whose staleness trips; physics telemetry is informational."""


@dataclass
class Track:
    """What the controller knows of one kind of node frame."""

    kind: type[MillMessage]
    stale_after_s: float
    receiver: E2EReceiver | None
    last: MillMessage | None = None
    received_s: float = -math.inf
    frames: int = 0
    counts: dict[str, int] = field(default_factory=dict)

    def age_s(self, now_s: float) -> float:
        """Seconds since the last fresh frame (inf before the first)."""
        return now_s - self.received_s


class TelemetryTracker:
    """Classifies every node frame with E2E and keeps the freshest message of each kind."""

    def __init__(self, codec: Codec, interlock: Interlock, *, e2e: bool = True, furnace: bool = True) -> None:
        """``e2e``: the reports carry an E2E counter and CRC; ``furnace``: furnace telemetry is expected."""
        self.tracks: dict[type[MillMessage], Track] = {}
        self.safety_relevant = tuple(k for k in SAFETY_RELEVANT if furnace or k is not FurnaceTelemetry)
        for kind in TRACKED:
            period = codec.cycle_time_s(kind) or 1.0
            receiver = (
                E2EReceiver(
                    error_limit=interlock.e2e_error_limit,
                    name=kind.__name__,
                    sequence_decay_frames=interlock.e2e_sequence_decay_frames,
                    min_decay_s=sequence_decay_s(interlock.e2e_sequence_decay_frames, period),
                )
                if kind.E2E and e2e
                else None
            )
            bound = max(interlock.stale_periods * period, interlock.min_stale_s)
            self.tracks[kind] = Track(kind, bound, receiver)
        self.startup_grace_s = interlock.startup_grace_s
        self.connected_s: float | None = None
        """When the node was first seen (s); streams not yet received are judged from then."""

    def connected(self, now_s: float) -> None:
        """The node has been seen: start the clock of the streams not yet received."""
        if self.connected_s is None:
            self.connected_s = now_s

    def accept(self, decoded: Decoded, now_s: float) -> MillMessage | None:
        """Classify a decoded node frame; return its message when fresh, else None."""
        track = self.tracks.get(decoded.kind)
        if track is None:
            return None
        status = track.receiver.check(decoded, now_s) if track.receiver is not None else E2EStatus.OK
        track.counts[status.value] = track.counts.get(status.value, 0) + 1
        if not status.fresh or decoded.message is None:
            return None
        track.last = decoded.message
        track.received_s = now_s
        track.frames += 1
        return decoded.message

    def stale(self, now_s: float) -> list[str]:
        """Why the safety-relevant telemetry is stale (empty when fresh)."""
        reasons = []
        for kind in self.safety_relevant:
            track = self.tracks[kind]
            age = track.age_s(now_s)
            if not track.frames:
                since_s = now_s - (now_s if self.connected_s is None else self.connected_s)
                bound = max(track.stale_after_s, self.startup_grace_s)
                if since_s > bound:
                    reasons.append(
                        f"{kind.__name__} stale: never received in {since_s:.2f} s since the node was seen "
                        f"> bound {bound:.2f} s (interlock.startup_grace_s)"
                    )
            elif age > track.stale_after_s:
                reasons.append(f"{kind.__name__} stale: age {age:.2f} s > bound {track.stale_after_s:.2f} s")
        return reasons

    def link_faults(self) -> list[str]:
        """Why a link is faulted by E2E errors (empty when healthy)."""
        reasons = (t.receiver.fault_reason() for t in self.tracks.values() if t.receiver is not None)
        return [reason for reason in reasons if reason is not None]

    def reset_links(self) -> None:
        """Forget E2E history (after an explicit reset)."""
        for track in self.tracks.values():
            if track.receiver is not None:
                track.receiver.reset()

    def health(self, now_s: float) -> dict[str, dict[str, object]]:
        """Per frame kind: age, bound, staleness and E2E counts (for status displays)."""
        result: dict[str, dict[str, object]] = {}
        for kind, track in self.tracks.items():
            age = track.age_s(now_s)
            result[kind.__name__] = {
                "age_s": None if math.isinf(age) else age,
                "stale_after_s": track.stale_after_s,
                "stale": age > track.stale_after_s,
                "frames": track.frames,
                "e2e": dict(track.counts),
                "e2e_score": track.receiver.score if track.receiver else 0,
                "e2e_sequence_score": track.receiver.sequence_score if track.receiver else 0,
            }
        return result


__all__ = ["SAFETY_RELEVANT", "TRACKED", "TelemetryTracker", "Track"]
