"""Shared helpers: the benchmark model, timing with repeats and medians, the machine record."""

from __future__ import annotations

import dataclasses
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from millctl.config import MillConfig, ModelVariant
from millctl.config.loader import default_config
from millctl.physics import MillModel


def bench_config() -> MillConfig:
    """The configuration every benchmark uses: the packaged Set A."""
    return default_config()


def corrected_model(config: MillConfig | None = None) -> MillModel:
    """Set A in the corrected variant (the physics the engine is built for; docs/model.md)."""
    model = MillModel.from_config(config or bench_config())
    return dataclasses.replace(model, variant=ModelVariant.CORRECTED)


def time_call(fn: Callable[[], Any], repeats: int = 5, number: int = 1) -> float:
    """Median over ``repeats`` of the CPU time per call (s) of ``number`` back-to-back calls (time.thread_time).

    The CPU time of this thread, so that other processes on a shared machine do not count (issue 40).
    """
    samples = []
    for _ in range(repeats):
        start = time.thread_time()
        for _ in range(number):
            fn()
        samples.append((time.thread_time() - start) / number)
    return statistics.median(samples)


def machine() -> dict[str, Any]:
    """Where and under what load the figures were measured."""
    load1, load5, load15 = os.getloadavg()
    return {
        "hostname": platform.node(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "loadavg": [round(load1, 2), round(load5, 2), round(load15, 2)],
        "time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }


def loadavg_now() -> list[float]:
    """os.getloadavg(), rounded (recorded again at the end of a run)."""
    return [round(x, 2) for x in os.getloadavg()]
