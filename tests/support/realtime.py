"""Real-time scheduling for the processes whose timing a hil test checks: the controller service and the node.

A mill controller runs its control loop under a real-time policy (SCHED_FIFO or
SCHED_RR, docs/deployment.md "Real-time priority"), so that other work on the
machine cannot delay a heartbeat or a trip. The hil tiers do the same for the
processes whose timing they assert (the 250 ms heartbeat watchdog, trips within
~0.1 s): ``.ci/test`` starts pytest under ``chrt --rr 10`` (``tests/hil/rt``), and only the service
and the node keep that policy; pytest itself, the probes, floods and clients run
at the normal policy, like any other job.

How the policy gets to the right processes: the udp_multicast cases run inside
an unprivileged user namespace (``tests/hil/in_netns``), where no process may
raise its own policy (CAP_SYS_NICE is the init namespace's, and RLIMIT_RTPRIO
cannot be raised without CAP_SYS_RESOURCE), but a policy set before entering it
is inherited through fork and exec. So :func:`take_over`, called once as pytest
starts, keeps one *launcher thread* at the inherited policy and returns the
test process's own thread to SCHED_OTHER (lowering is always allowed); a
process started from the launcher thread inherits the real-time policy, any
other starts at the normal one. Started without a real-time policy (a developer's
``pytest tests/hil``, or where ``chrt`` is not permitted), everything runs at
the normal policy, as before, and :func:`describe` says so.

Nothing started this way may spin: the kernel leaves ordinary tasks only
``1 - sched_rt_runtime_us/sched_rt_period_us`` (5 %) of a CPU that a real-time
task keeps busy. The service's control loop and the node's tick loop sleep
until their next tick, so they take the CPU only for the work of each tick.
"""

from __future__ import annotations

import os
import subprocess
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

REALTIME_POLICIES = {os.SCHED_FIFO: "SCHED_FIFO", os.SCHED_RR: "SCHED_RR"}


@dataclass(frozen=True)
class Policy:
    """A real-time scheduling policy and its priority (1–99)."""

    policy: int
    priority: int

    def __str__(self) -> str:
        return f"{REALTIME_POLICIES[self.policy]} priority {self.priority}"


def current_policy() -> Policy | None:
    """The calling thread's real-time policy, or None when it runs at a normal one."""
    policy = os.sched_getscheduler(0)
    if policy not in REALTIME_POLICIES:
        return None
    return Policy(policy, os.sched_getparam(0).sched_priority)


def _start(argv: list[str], kwargs: dict[str, Any]) -> subprocess.Popen[bytes]:
    proc: subprocess.Popen[bytes] = subprocess.Popen(argv, **kwargs)
    return proc


class Launcher:
    """One thread that keeps the real-time policy it was created with, and starts processes from there.

    A child inherits the scheduling policy of the thread that forks it, so
    ``Popen`` called on this thread starts the child at the policy. The thread
    waits on its work queue between calls (it never spins).
    """

    def __init__(self, policy: Policy) -> None:
        self.policy = policy
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="realtime-launcher")
        created = self._executor.submit(current_policy).result()  # creates the thread now, at the caller's policy
        if created != policy:
            raise RuntimeError(f"the launcher thread runs at {created}, not {policy}")

    def popen(self, argv: list[str], **kwargs: Any) -> subprocess.Popen[bytes]:
        """``subprocess.Popen(argv, **kwargs)``, started from the launcher thread (so at its policy)."""
        return self._executor.submit(_start, argv, kwargs).result()

    def start_thread(self, thread: threading.Thread) -> None:
        """``thread.start()`` from the launcher thread: a new thread inherits its creator's policy."""
        self._executor.submit(thread.start).result()


_launcher: Launcher | None = None


def take_over() -> Policy | None:
    """Keep a launcher thread at this thread's real-time policy and return this thread to SCHED_OTHER.

    Called once, before pytest starts any thread of its own (``tests/conftest.py``,
    ``pytest_configure``); returns the policy kept (None when there was none). The
    nice value stays what it was (``.ci/test`` starts the hil tiers at ``nice -n -10``).
    """
    global _launcher
    if _launcher is not None:
        return _launcher.policy
    policy = current_policy()
    if policy is None:
        return None
    _launcher = Launcher(policy)
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    return policy


def popen(argv: list[str], *, realtime: bool, **kwargs: Any) -> subprocess.Popen[bytes]:
    """Start ``argv``; with ``realtime``, at the real-time policy the test process was started with (if any)."""
    if realtime and _launcher is not None:
        return _launcher.popen(argv, **kwargs)
    return _start(argv, kwargs)


def launcher_policy() -> Policy | None:
    """The real-time policy kept for the service and node (None: they run at the normal policy)."""
    return _launcher.policy if _launcher is not None else None


def start_thread(thread: threading.Thread, *, realtime: bool) -> None:
    """Start ``thread``; with ``realtime``, at the real-time policy the test process was started with (if any).

    For a test's instrument that stands in for a device on the bus, whose timing the
    bound under test assumes (the second sender answering each genuine frame at once).
    """
    if realtime and _launcher is not None:
        _launcher.start_thread(thread)
    else:
        thread.start()


def describe() -> str:
    """Which policy the service and node of the hil tests run at, for pytest's header."""
    if _launcher is None:
        return (
            "hil: the service and node run at the normal scheduling policy (pytest was not started under a "
            "real-time policy; .ci/test starts the hil tiers under `chrt --rr 10` where permitted: tests/hil/rt)"
        )
    return f"hil: the service and node run at {_launcher.policy} (real-time); pytest and its helpers at SCHED_OTHER"


__all__ = [
    "REALTIME_POLICIES",
    "Launcher",
    "Policy",
    "current_policy",
    "describe",
    "launcher_policy",
    "popen",
    "start_thread",
    "take_over",
]
