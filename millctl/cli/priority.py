"""Background work runs below the mill (SAFETY 27): design studies and benchmarks lower their CPU priority.

A study or a benchmark started on the PC that controls the mill competes with
the control loop for the CPU; at the normal policy a busy study can make the
loop late past the node's watchdog (docs/safety.md#host-starvation). So
``millctl study run``, ``millctl bench`` and ``python -m bench`` raise their
niceness by :data:`BACKGROUND_NICE` at start (their worker processes inherit
it); ``--no-nice`` keeps the priority they were started with.
"""

from __future__ import annotations

import argparse
import logging
import os

log = logging.getLogger(__name__)

BACKGROUND_NICE = 10
"""The niceness added to a study's or a benchmark's process (nice(1)'s default)."""
NO_NICE_FLAG = "--no-nice"


def add_priority_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--no-nice``."""
    parser.add_argument(
        NO_NICE_FLAG, dest="no_nice", action="store_true",
        help=f"keep the CPU priority this was started with (default: niceness +{BACKGROUND_NICE}, below the mill)",
    )


def lower_priority(opt_out: bool, what: str) -> int | None:
    """Raise this process's niceness by BACKGROUND_NICE unless ``opt_out``; the niceness now (None: unchanged)."""
    if opt_out:
        return None
    try:
        niceness = os.nice(BACKGROUND_NICE)
    except OSError as exc:  # e.g. a sandbox that forbids it: the work runs anyway, at the priority it has
        log.warning("%s: cannot lower the CPU priority (%s); it competes with the control loop", what, exc)
        return None
    log.info("%s runs at niceness %d (below the mill's control loop; %s keeps the priority)", what, niceness,
             NO_NICE_FLAG)
    return niceness


__all__ = ["BACKGROUND_NICE", "NO_NICE_FLAG", "add_priority_option", "lower_priority"]
