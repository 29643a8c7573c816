"""How long a test may wait for a process: bounds that stretch with the machine's measured slowness.

The tests hold two kinds of time bound, and only one of them may stretch:

* **Physical bounds** (a watchdog, a trip's reaction time) come from the
  config and the DBC and are what the test asserts. Load does not change them;
  only the VM's measured emulation factor does (``scenario_support.bound_scale``).
* **Process waits** (a service starting, a state being reached, a process
  exiting) are safety nets sized for an idle machine. They are a
  :class:`Deadline`: its clock runs at the share of a CPU a runnable process
  gets right now, so on a machine where 8 runnable tasks share 2 CPUs a 30 s
  wait lasts up to ~120 s, and on an idle one exactly 30 s. Everything is
  multiplied by :func:`time_scale` (``MILLCTL_TIME_SCALE``: the VM's emulation
  slowdown, measured by ``tests/vm/run`` at boot).

The CPU share is sampled at every check from ``/proc/loadavg``: the larger of
the 1-minute load average and the tasks runnable at that instant (less the
one reading it), per CPU. A wait stretches at most :data:`MAX_STRETCH` times,
so a process that hangs still fails the test.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

MAX_STRETCH = 8.0
"""The most a wait stretches under load (a hang must still fail, and before pytest-timeout does)."""


def time_scale() -> float:
    """The emulation factor every wait and the VM's bounds are multiplied by (``MILLCTL_TIME_SCALE``, default 1)."""
    text = os.environ.get("MILLCTL_TIME_SCALE", "1")
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"MILLCTL_TIME_SCALE must be a number >= 1, got {text!r}") from None
    if not value >= 1:
        raise ValueError(f"MILLCTL_TIME_SCALE must be >= 1, got {value}")
    return value


def runnable_per_cpu() -> float:
    """Tasks competing for each CPU now: max(1-min load average, runnable tasks less this one) / CPUs."""
    fields = Path("/proc/loadavg").read_text().split()
    load_1min = float(fields[0])
    runnable_now = int(fields[3].split("/")[0]) - 1
    return max(load_1min, runnable_now) / (os.cpu_count() or 1)


def cpu_share() -> float:
    """The share of a CPU a runnable process gets now (1 on an idle machine, at least 1/MAX_STRETCH)."""
    return 1.0 / min(max(runnable_per_cpu(), 1.0), MAX_STRETCH)


def stretched(seconds: float) -> float:
    """``seconds`` (on an idle machine) as a wall-time bound for one blocking call: scaled and stretched by load now.

    For calls that take a timeout (``Popen.wait``, ``bus.recv``); a polling loop uses :class:`Deadline`,
    which also follows load that changes during the wait.
    """
    return seconds * time_scale() / cpu_share()


class Deadline:
    """A wait of ``seconds`` (on an idle machine) that stretches with load and with ``time_scale()``.

    :meth:`expired` advances the deadline's clock by the wall time since the
    last check times the CPU share measured now; it expires when that clock
    reaches ``seconds × time_scale()``.
    """

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds * time_scale()
        self._credit_s = 0.0
        self._started = self._checked = time.monotonic()

    def expired(self) -> bool:
        """True once the process waited for has had ``seconds`` of (scaled) CPU-share time."""
        now = time.monotonic()
        self._credit_s += (now - self._checked) * cpu_share()
        self._checked = now
        return self._credit_s >= self.seconds

    @property
    def waited_s(self) -> float:
        """Wall time since the deadline was set (for messages)."""
        return time.monotonic() - self._started

    def describe(self) -> str:
        """``"30.0 s (waited 74.2 s under load)"``, for failure messages."""
        waited = self.waited_s
        if waited > self.seconds * 1.05:
            return f"{self.seconds:.1f} s (waited {waited:.1f} s: the bound stretches with load)"
        return f"{self.seconds:.1f} s"

    def remaining_s(self) -> float:
        """A conservative wall-time remainder: the credit still due at the current CPU share."""
        self.expired()
        return max(self.seconds - self._credit_s, 0.0) / cpu_share()


# --- calibration: how much slower this machine runs than another (the VM against its host) -----------------------


def _workload() -> None:
    """A fixed slice of what the hil processes do: interpreted arithmetic, small objects, pipe system calls."""
    table: dict[int, float] = {}
    acc = 0.0
    for i in range(20_000):
        acc += (i * 0.5) ** 0.5
        table[i & 255] = acc
    read_end, write_end = os.pipe()
    try:
        for _ in range(300):
            os.write(write_end, b"12345678")  # a frame's worth through the kernel (no file system:
            os.read(read_end, 8)  # the VM's root is 9p, where one stat costs a round trip to the host)
    finally:
        os.close(read_end)
        os.close(write_end)


def calibration_s(repeats: int = 7, clock: str = "wall") -> float:
    """The workload's time (s): the fastest of ``repeats`` runs by CPU time, or their median by wall time.

    ``clock="cpu"`` is the host's reference: this process's CPU time, the fastest run (meant to be what
    the host's load cannot inflate; beside a busy VM it still varies 3.5-5.7 ms: tests/vm/README.md,
    "Speed"). ``clock="wall"`` is the VM's measurement: wall time, which is what its waits are made of,
    and the median run, so that the figure is the VM's typical speed on the host as it is loaded now,
    not its best moment.
    """
    if clock not in ("cpu", "wall"):
        raise ValueError(f"the calibration clock must be 'cpu' or 'wall', got {clock!r}")
    if repeats < 1:
        raise ValueError(f"the calibration needs at least 1 run, got {repeats}")
    timer = time.process_time if clock == "cpu" else time.perf_counter
    runs = []
    for _ in range(repeats):
        start = timer()
        _workload()
        runs.append(timer() - start)
    return min(runs) if clock == "cpu" else statistics.median(runs)


SLOWEST_PASSING_HOST_S = 0.0048
"""The calibration's CPU time (s) on the slowest host the tiers' timing is known to pass on, loaded.

The VM's scale says how many times the config's periods must stretch for processes in the VM to keep
them as the host's processes do. The host's own figure varies with the moment: 3.05-5.75 ms on the
2-core CI machine (tests/vm/README.md, "Speed"), while the VM's speed did not follow it. Measured at a
quiet moment it stretched every period, wait and window of the VM's run up to 1.6x more than needed,
and the tier ran out of CI's 90 minutes. The host tiers pass loaded at 4.8-5.7 ms (the loaded
clean-clone CI runs of e77800c: 4.835 and 5.749 ms), so a VM as fast as such a host needs no stretch,
and a host faster than that does not make the VM any slower.
"""


def host_reference_s(measured_s: float | None = None) -> float:
    """The host's reference for the VM's scale: ``measured_s``, at least :data:`SLOWEST_PASSING_HOST_S`.

    ``measured_s`` defaults to :func:`calibration_s` (CPU time, fastest run) measured now.
    """
    if measured_s is None:
        measured_s = calibration_s(clock="cpu")
    return max(measured_s, SLOWEST_PASSING_HOST_S)


def slowdown_against(reference_s: float, measured_s: float | None = None) -> float:
    """How many times slower this machine runs than the reference: ``measured_s / reference_s``, at least 1.

    ``measured_s`` defaults to :func:`calibration_s` (wall time, median) measured now.
    """
    if not reference_s > 0:
        raise ValueError(f"the calibration reference must be a positive time in s, got {reference_s}")
    if measured_s is None:
        measured_s = calibration_s()
    return max(measured_s / reference_s, 1.0)


REFERENCE_ENV = "MILLCTL_PACE_REFERENCE_S"
"""The host's calibration reference (s of CPU), which ``tests/vm/run`` passes into the VM."""


def slowdown_now() -> float:
    """The slowdown against the host measured now (about 1 s in the VM), at least :func:`time_scale`.

    For a load a scenario generates (a flood, a babble), sized to what the machine manages at that
    moment: the VM slows down further when the host gets busier after the run measured its scale.
    Without the host's reference (``$MILLCTL_PACE_REFERENCE_S``, set in the VM) it is :func:`time_scale`.
    """
    reference = os.environ.get(REFERENCE_ENV)
    if not reference:
        return time_scale()
    return max(slowdown_against(float(reference)), time_scale())


MEASURED_ENV = "MILLCTL_TIME_SCALE_MEASURED"
"""``1`` when ``$MILLCTL_TIME_SCALE`` is the VM's own measurement (``tests/vm/guest``), not a caller's forced figure."""


def scale_for_a_test(run_scale: float) -> float:
    """The time scale for a hil test starting now: the slowdown measured now, at least the run's ``run_scale``.

    The VM measures its scale once as it boots, but a run lasts half an hour and the host's load
    changes under it (another job starts, a CPU hog runs a spell): a scale that was right at boot
    then leaves the tests of a busier moment too little time. So each test measures it again as it
    starts (about 1 s in the VM) and its waits, its config and its bounds follow that figure. Never
    below the run's own figure, so that a calm moment does not tighten what the run was sized for.
    Where the scale is not a measurement (the host; ``MILLCTL_TIME_SCALE`` forced by the caller,
    no ``$MILLCTL_TIME_SCALE_MEASURED``; no host reference) it is ``run_scale`` as it is.
    """
    reference = os.environ.get(REFERENCE_ENV)
    if os.environ.get(MEASURED_ENV) != "1" or not reference:
        return run_scale
    return max(slowdown_against(float(reference)), run_scale)


def main(argv: list[str]) -> int:
    """``python -m tests.support.pace --reference`` (host) / ``--scale REF_S`` (VM): print the figure."""
    if argv == ["--reference"]:
        measured = calibration_s(clock="cpu")
        reference = host_reference_s(measured)
        if reference > measured:
            print(
                f"pace: this host ran the calibration in {measured:.6f} s of CPU; the reference is "
                f"{reference:.6f} s, the slowest host the tiers pass on (SLOWEST_PASSING_HOST_S)",
                file=sys.stderr,
            )
        print(f"{reference:.6f}")
        return 0
    if len(argv) == 2 and argv[0] == "--scale":
        print(f"{slowdown_against(float(argv[1])):.2f}")
        return 0
    print("usage: python -m tests.support.pace --reference | --scale REFERENCE_S", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))


__all__ = [
    "MAX_STRETCH",
    "MEASURED_ENV",
    "REFERENCE_ENV",
    "SLOWEST_PASSING_HOST_S",
    "Deadline",
    "calibration_s",
    "cpu_share",
    "host_reference_s",
    "runnable_per_cpu",
    "scale_for_a_test",
    "slowdown_against",
    "slowdown_now",
    "stretched",
    "time_scale",
]
