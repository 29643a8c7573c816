"""The control lease, stepped with a manual clock: one holder, renewal, expiry, explicit takeover, and a request
judged by the lease as it was when the request arrived."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import httpx
import pytest

from millctl.clock import ManualClock
from millctl.service import create_app
from millctl.service.lease import LeaseError, LeaseManager
from tests.support.service import DEMO_RECIPE, advance, stepped_runtime


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


def test_a_lease_live_when_its_request_arrived_is_good_for_the_whole_request() -> None:
    clock = ManualClock()
    leases = LeaseManager(clock, ttl_s=30.0)
    lease, _ = leases.take("api:alice")
    arrived_s = clock.now()
    leases.check(lease.lease_id)  # at arrival: renews
    clock.advance(31.0)  # the service's own work on the request (a long pre-flight)
    assert leases.check(lease.lease_id, arrived_s=arrived_s) is lease
    clock.advance(31.0)
    with pytest.raises(LeaseError, match="expired 1 s ago"):  # a later request is judged at its own arrival
        leases.check(lease.lease_id, arrived_s=clock.now())


def test_a_lease_taken_over_during_a_request_is_refused_at_its_second_check() -> None:
    clock = ManualClock()
    leases = LeaseManager(clock, ttl_s=30.0)
    first, _ = leases.take("api:tui")
    arrived_s = clock.now()
    leases.check(first.lease_id)
    clock.advance(31.0)
    leases.take("api:cli", force=True)  # expired meanwhile, and taken over explicitly
    with pytest.raises(LeaseError, match="held by api:cli"):
        leases.check(first.lease_id, arrived_s=arrived_s)


async def test_a_recipe_whose_pre_flight_outlasts_the_lease_still_starts(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The service's own slowness (the first pre-flight loads the compiled kernels: over 30 s under emulation,
    seen in the vcan VM) is not the client's: its lease was live when the request arrived."""
    runtime = stepped_runtime(tmp_path)
    try:
        lease = runtime.leases.take("api:alice")[0].lease_id
        prepare = runtime.recipe.prepare

        def slow_prepare(*args: Any) -> Any:
            assert isinstance(runtime.clock, ManualClock)
            runtime.clock.advance(runtime.leases.ttl_s + 1.0)
            return prepare(*args)

        monkeypatch.setattr(runtime.recipe, "prepare", slow_prepare)
        transport = httpx.ASGITransport(app=create_app(runtime))
        async with httpx.AsyncClient(transport=transport, base_url="http://millctl") as http:
            headers = {"X-Millctl-Lease": lease}
            assert (await http.post("/v1/arm", headers=headers)).status_code == 200
            advance(runtime, 0.5)
            recipe = {"name": "demo", "text": DEMO_RECIPE.read_text()}
            response = await http.post("/v1/recipe/run", headers=headers, json=recipe)
        assert response.status_code == 200, response.text
        assert response.json()["active"] is True
    finally:
        runtime.close()
