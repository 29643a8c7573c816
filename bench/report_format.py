"""Number formatting shared by the benchmark's document sections (:mod:`bench.report`, :mod:`bench.report_wp`)."""

from __future__ import annotations

import math


def g(x: float | None, digits: int = 3) -> str:
    """A number to ``digits`` significant digits; '—' for None or nan."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "—"
    return f"{x:.{digits}g}"


def ms(x: float | None) -> str:
    """Seconds shown in ms."""
    return "—" if x is None else g(x * 1e3)


__all__ = ["g", "ms"]
