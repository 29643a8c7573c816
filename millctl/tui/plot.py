"""A braille plot of the enforced limit curve ω_r,max(ω_v) with the operating point marked.

The curve comes from the service (``GET /v1/envelope``), so the plot shows
exactly what the interlock enforces. Each character cell holds 2 × 4 braille
dots. The curve is green where the configured law is the every-cycle bound
and yellow where it is not (docs/model.md); the measured operating point is
``●`` (red when above the limit) and the commanded target ``○``.
"""

from __future__ import annotations

import bisect
import functools
import math
from dataclasses import dataclass

from rich.text import Text

from millctl.api import EnvelopeOut

BRAILLE_BASE = 0x2800
_DOT_BITS = ((0x01, 0x08), (0x02, 0x10), (0x04, 0x20), (0x40, 0x80))
"""Bit of the braille dot at (row 0..3 from the top, column 0..1) of a cell."""


@dataclass(frozen=True)
class Curve:
    """The limit curve: ω_v grid (rpm), ω_r limit (rpm, None where unbounded), every-cycle flags, axis maxima."""

    omega_v_rpm: tuple[float, ...]
    limit_rpm: tuple[float | None, ...]
    every_cycle: tuple[bool, ...]
    rotary_max_rpm: float
    vibration_max_rpm: float

    @classmethod
    def from_envelope(cls, envelope: EnvelopeOut) -> Curve:
        """Build from the service's ``/v1/envelope`` answer."""
        points = envelope.points
        return cls(
            omega_v_rpm=tuple(p.vibration_rpm for p in points),
            limit_rpm=tuple(p.limit_rotary_rpm for p in points),
            every_cycle=tuple(p.law_is_every_cycle for p in points),
            rotary_max_rpm=envelope.rotary_max_rpm,
            vibration_max_rpm=envelope.vibration_max_rpm,
        )

    def limit_at(self, omega_v_rpm: float) -> float:
        """The limit (rpm) at ``omega_v_rpm``, linearly interpolated and capped at the rotary maximum (display only)."""
        xs, cap = self.omega_v_rpm, self.rotary_max_rpm
        ys = [cap if y is None else min(float(y), cap) for y in self.limit_rpm]
        if omega_v_rpm <= xs[0]:
            return ys[0]
        for i in range(1, len(xs)):
            if omega_v_rpm <= xs[i]:
                frac = (omega_v_rpm - xs[i - 1]) / (xs[i] - xs[i - 1])
                return ys[i - 1] + frac * (ys[i] - ys[i - 1])
        return ys[-1]

    def y_max_rpm(self, *shown_rpm: float) -> float:
        """Top of the plot (rpm): 15 % above the highest limit or shown speed, rounded up to 10, at most ω_r max."""
        limits = [float(y) for y in self.limit_rpm if y is not None] or [self.rotary_max_rpm]
        top = 1.15 * max(*limits, *shown_rpm)
        return min(math.ceil(top / 10.0) * 10.0, self.rotary_max_rpm)

    def every_cycle_at(self, omega_v_rpm: float) -> bool:
        """Whether the law is the every-cycle bound at the grid point at or below ``omega_v_rpm``."""
        index = bisect.bisect_right(self.omega_v_rpm, omega_v_rpm) - 1
        return self.every_cycle[min(max(index, 0), len(self.every_cycle) - 1)]

    def first_not_every_cycle_rpm(self) -> float | None:
        """The lowest ω_v (rpm) of the grid where the law is not the every-cycle bound, or None."""
        for w_v, every in zip(self.omega_v_rpm, self.every_cycle, strict=True):
            if not every:
                return w_v
        return None


@functools.lru_cache(maxsize=16)
def _curve_rows(curve: Curve, cols: int, rows: int, y_max: float) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The curve as braille rows, and each column's style (green: every-cycle bound; yellow: not)."""
    dots_x, dots_y = 2 * cols, 4 * rows
    cells = [[0] * cols for _ in range(rows)]
    for dx in range(dots_x):
        frac = curve.limit_at(curve.vibration_max_rpm * dx / (dots_x - 1)) / y_max
        dy = dots_y - 1 - min(max(round(frac * (dots_y - 1)), 0), dots_y - 1)
        cells[dy // 4][dx // 2] |= _DOT_BITS[dy % 4][dx % 2]
    lines = tuple("".join(chr(BRAILLE_BASE + bits) for bits in row) for row in cells)
    styles = tuple("green" if curve.every_cycle_at(curve.vibration_max_rpm * col / max(cols - 1, 1)) else "yellow"
                   for col in range(cols))
    return lines, styles


def render_plot(
    curve: Curve,
    width: int,
    height: int,
    point: tuple[float, float] | None = None,
    target: tuple[float, float] | None = None,
) -> Text:
    """The plot as ``height`` lines of ``width`` cells (axis labels included); points are (ω_v, ω_r) in rpm."""
    y_max = curve.y_max_rpm(target[1] if target else 0.0, point[1] if point else 0.0)
    label_w = len(f"{y_max:.0f}") + 1
    cols, rows = max(width - label_w, 4), max(height - 1, 2)
    lines, styles = _curve_rows(curve, cols, rows, y_max)

    def cell_of(pair: tuple[float, float]) -> tuple[int, int] | None:
        w_v, w_r = pair
        if not (math.isfinite(w_v) and math.isfinite(w_r)):
            return None
        col = min(max(round(w_v / curve.vibration_max_rpm * (cols - 1)), 0), cols - 1)
        row = rows - 1 - min(max(round(w_r / y_max * (rows - 1)), 0), rows - 1)
        return row, col

    marks: dict[tuple[int, int], tuple[str, str]] = {}
    if target is not None and (cell := cell_of(target)) is not None:
        marks[cell] = ("○", "bold cyan")
    if point is not None and (cell := cell_of(point)) is not None:
        outside = point[1] > curve.limit_at(point[0])
        marks[cell] = ("●", "bold red" if outside else "bold bright_white")
    text = Text(no_wrap=True, overflow="crop")
    for row in range(rows):
        label = f"{y_max:.0f}" if row == 0 else ("0" if row == rows - 1 else "")
        text.append(label.rjust(label_w - 1) + "┤" if label else " " * (label_w - 1) + "│", style="dim")
        start = len(text)
        line = list(lines[row])
        for (mark_row, col), (char, _) in marks.items():
            if mark_row == row:
                line[col] = char
        text.append("".join(line) + "\n")
        run_start = 0
        for col in range(1, cols + 1):  # one span per run of equal style, not one per cell
            if col == cols or styles[col] != styles[run_start]:
                text.stylize(styles[run_start], start + run_start, start + col)
                run_start = col
        for (mark_row, col), (_, style) in marks.items():
            if mark_row == row:
                text.stylize(style, start + col, start + col + 1)
    axis = f"0 ω_v rpm → {curve.vibration_max_rpm:.0f}"
    text.append(" " * label_w + axis.ljust(cols)[:cols], style="dim")
    return text


__all__ = ["Curve", "render_plot"]
