"""The control lease: one client commands the mill at a time, the others watch.

A client takes control and gets a lease id, which it sends with every
command; each accepted command (or another take by the holder) renews it. A
lease not renewed for ``ttl_s`` has expired: its holder can no longer
command, and another client may take over only by asking explicitly
(``force``), so that a takeover is always a deliberate, recorded act. A live
lease is never taken away. E-stop and a controlled STOP need no lease at all:
any client may stop the mill at any time (SAFETY 24).
"""

from __future__ import annotations

import secrets
import threading
from dataclasses import dataclass

from millctl.clock import Clock
from millctl.errors import InterlockError

DEFAULT_TTL_S = 30.0
"""A lease expires this long after it was last renewed (s)."""


class LeaseError(InterlockError):
    """A command without control: no lease, a wrong or expired lease, or control held by another client."""

    def __init__(self, message: str, holder: str | None = None) -> None:
        self.holder = holder
        super().__init__(message)


@dataclass
class Lease:
    """One client's hold on control."""

    lease_id: str
    holder: str
    renewed_s: float
    ttl_s: float

    def remaining_s(self, now_s: float) -> float:
        """Time until it expires (s); negative once expired."""
        return self.renewed_s + self.ttl_s - now_s


class LeaseManager:
    """Grants, renews, checks and releases the one control lease (thread-safe)."""

    def __init__(self, clock: Clock, ttl_s: float = DEFAULT_TTL_S) -> None:
        if ttl_s <= 0.0:
            raise ValueError(f"lease ttl_s = {ttl_s} must be > 0")
        self.clock = clock
        self.ttl_s = ttl_s
        self._lease: Lease | None = None
        self._lock = threading.Lock()

    @property
    def current(self) -> Lease | None:
        """The lease, live or expired, or None when nobody has taken control."""
        return self._lease

    def take(self, holder: str, *, lease_id: str | None = None, force: bool = False) -> tuple[Lease, str | None]:
        """Grant control to ``holder``; return the lease and whom it was taken over from (expired, forced).

        The holder renews its lease by taking again with its lease id.
        """
        with self._lock:
            now = self.clock.now()
            old = self._lease
            taken_from = None
            if old is not None and lease_id is not None and secrets.compare_digest(old.lease_id, lease_id):
                old.renewed_s = now  # the holder renews its own lease, even one that lapsed
                return old, None
            if old is not None:
                remaining = old.remaining_s(now)
                if remaining > 0.0:
                    raise LeaseError(
                        f"control is held by {old.holder} (lease live for another {remaining:.0f} s); "
                        "wait until it is released, or ask its holder",
                        holder=old.holder,
                    )
                if not force:
                    raise LeaseError(
                        f"control is held by {old.holder}, whose lease expired {-remaining:.0f} s ago; "
                        "take it over explicitly with force",
                        holder=old.holder,
                    )
                taken_from = old.holder
            self._lease = Lease(secrets.token_urlsafe(18), holder, now, self.ttl_s)
            return self._lease, taken_from

    def check(self, lease_id: str | None, *, arrived_s: float | None = None) -> Lease:
        """Renew and return the lease if ``lease_id`` is the live lease; otherwise raise :class:`LeaseError`.

        ``arrived_s`` (clock time) is when the request carrying the lease arrived: a lease live then
        stays good for the whole request, so a request the service itself takes long over (a recipe's
        pre-flight, checked again before the start) is not refused for the service's own slowness.
        Who holds the lease is judged now: a lease released or taken over since is refused.
        """
        with self._lock:
            now = self.clock.now()
            judged = now if arrived_s is None else min(arrived_s, now)
            lease = self._lease
            if lease is None:
                raise LeaseError("nobody has control: take control first (POST /v1/control/take)")
            if lease_id is None or not secrets.compare_digest(lease.lease_id, lease_id):
                if lease.remaining_s(now) > 0.0:
                    raise LeaseError(f"control is held by {lease.holder}", holder=lease.holder)
                raise LeaseError(
                    f"control is held by {lease.holder}, whose lease expired; take it over with force",
                    holder=lease.holder,
                )
            if lease.remaining_s(judged) <= 0.0:
                raise LeaseError(
                    f"your lease ({lease.holder}) expired {-lease.remaining_s(judged):.0f} s ago: take control again",
                    holder=lease.holder,
                )
            lease.renewed_s = now
            return lease

    def holder_of(self, lease_id: str | None) -> str | None:
        """Who holds the lease ``lease_id`` (live or expired), or None: names a stop's sender; renews nothing."""
        lease = self._lease
        if lease is None or lease_id is None or not secrets.compare_digest(lease.lease_id, lease_id):
            return None
        return lease.holder

    def release(self, lease_id: str | None) -> Lease:
        """Give control back; only with the lease id (expired or not). Return the released lease."""
        with self._lock:
            lease = self._lease
            if lease is None:
                raise LeaseError("nobody has control: nothing to release")
            if lease_id is None or not secrets.compare_digest(lease.lease_id, lease_id):
                raise LeaseError(f"control is held by {lease.holder}: only its holder can release it",
                                 holder=lease.holder)
            self._lease = None
            return lease


__all__ = ["DEFAULT_TTL_S", "Lease", "LeaseError", "LeaseManager"]
