"""The control lease, stepped with a manual clock: one holder, renewal, expiry, explicit takeover."""

from __future__ import annotations

import pytest

from millctl.clock import ManualClock
from millctl.service.lease import LeaseError, LeaseManager


def test_one_holder_at_a_time_and_only_it_may_command() -> None:
    clock = ManualClock()
    leases = LeaseManager(clock, ttl_s=30.0)
    lease, taken_from = leases.take("api:alice")
    assert taken_from is None
    with pytest.raises(LeaseError) as held:
        leases.take("api:bob")
    assert held.value.holder == "api:alice"
    with pytest.raises(LeaseError):
        leases.check("not-the-lease")
    with pytest.raises(LeaseError):
        leases.check(None)
    assert leases.check(lease.lease_id) is lease
    with pytest.raises(LeaseError):
        leases.release("not-the-lease")
    leases.release(lease.lease_id)
    assert leases.current is None
    other, _ = leases.take("api:bob")
    assert other.holder == "api:bob"


def test_commands_renew_and_an_unrenewed_lease_expires() -> None:
    clock = ManualClock()
    leases = LeaseManager(clock, ttl_s=30.0)
    lease, _ = leases.take("api:alice")
    clock.advance(20.0)
    leases.check(lease.lease_id)  # renews
    clock.advance(20.0)
    leases.check(lease.lease_id)  # still live: 20 s after the renewal
    clock.advance(31.0)
    with pytest.raises(LeaseError, match="expired"):
        leases.check(lease.lease_id)
    renewed, _ = leases.take("api:alice", lease_id=lease.lease_id)  # the holder may take its own back
    assert renewed.lease_id == lease.lease_id


def test_force_takes_over_only_an_expired_lease() -> None:
    clock = ManualClock()
    leases = LeaseManager(clock, ttl_s=30.0)
    first, _ = leases.take("api:tui")
    with pytest.raises(LeaseError, match="live"):
        leases.take("api:cli", force=True)
    clock.advance(31.0)
    with pytest.raises(LeaseError, match="force"):
        leases.take("api:cli")  # expired, but a takeover must be explicit
    second, taken_from = leases.take("api:cli", force=True)
    assert taken_from == "api:tui"
    with pytest.raises(LeaseError):
        leases.check(first.lease_id)
    assert leases.check(second.lease_id).holder == "api:cli"
