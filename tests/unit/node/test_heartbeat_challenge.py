"""Heartbeat freshness on the node: only an echo of a live, not superseded challenge feeds the watchdog (SAFETY 16)."""

from __future__ import annotations

from firmware_sim.link import LinkMonitor
from millctl.config import MillConfig
from millctl.protocol import ControllerState, FaultCode, Heartbeat, NodeState, NodeStatus

from .conftest import Bench


def test_a_heartbeat_with_a_fresh_counter_but_no_live_challenge_never_feeds_the_watchdog(bench: Bench) -> None:
    bench.run_at(40.0, 150.0)
    timing = bench.config.timing
    fed = bench.node.link.fresh_heartbeats
    t_last = bench.clock.now()
    for _ in range(40):  # fresh counters, every echo one off the challenge in play
        bench.send(Heartbeat(ControllerState.RUNNING, (bench.challenge() + 1) % 65536))
        bench.step(timing.heartbeat_period_s, heartbeat=False)
        if bench.node.state is NodeState.FAULT:
            break
    assert bench.node.state is NodeState.FAULT and bench.node.first_fault is FaultCode.WATCHDOG
    assert bench.node.link.fresh_heartbeats == fed and bench.node.link.expired_echoes > 0
    assert bench.clock.now() - t_last <= timing.watchdog_timeout_s + timing.heartbeat_period_s + bench.tick_s


def test_every_node_status_carries_a_new_challenge(bench: Bench) -> None:
    bench.step(1.0)
    challenges = [d.message.challenge for d in bench.received if isinstance(d.message, NodeStatus)]
    assert len(challenges) >= 19 and len(set(challenges)) == len(challenges)  # no repeat within 65 536


def test_an_echo_is_fresh_only_while_live_and_not_older_than_the_last_accepted(config: MillConfig) -> None:
    link = LinkMonitor(config)
    lifetime_s = config.timing.challenge_lifetime_s
    first = link.issue_challenge(0.0)
    second = link.issue_challenge(0.05)
    assert second != first  # consecutive challenges never repeat (ChallengeSequence)
    assert link.echo_fresh(first, 0.06)  # an older challenge, while nothing newer was echoed yet
    assert link.echo_fresh(second, 0.07)
    assert link.echo_fresh(second, 0.08)  # the same echo again (no newer NodeStatus heard yet)
    assert not link.echo_fresh(first, 0.09)  # superseded: a recording of it is worth nothing now
    assert not link.echo_fresh(second, 0.05 + lifetime_s + 0.01)  # expired
    assert not link.echo_fresh(12345 if 12345 not in (first, second) else 54321, 0.1)
