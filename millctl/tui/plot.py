"""A braille plot of the enforced limit curve ω_r,max(ω_v) with the operating point marked.

The curve comes from the service (``GET /v1/envelope``), so the plot shows
exactly what the interlock enforces. Each character cell holds 2 × 4 braille
dots. The curve is green where the configured law is the every-cycle bound
and yellow where it is not (from the service's regime warning,
:mod:`millctl.safety.regime`, the number ``millctl limits`` prints); the
measured operating point is ``●`` (red when above the limit) and the
commanded target ``○``. The envelope view (:mod:`millctl.tui.envelope`) adds
the other laws as curves of their own colour under the enforced one.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

from rich.text import Text

from millctl.api import EnvelopeOut, StatusOut

BRAILLE_BASE = 0x2800
_DOT_BITS = ((0x01, 0x08), (0x02, 0x10), (0x04, 0x20), (0x40, 0x80))
"""Bit of the braille dot at (row 0..3 from the top, column 0..1) of a cell."""


@dataclass(frozen=True)
class Curve:
    """A limit curve: ω_v grid (rpm), ω_r limit (rpm, None where unbounded), where the law is the every-cycle bound."""

    omega_v_rpm: tuple[float, ...]
    limit_rpm: tuple[float | None, ...]
    not_every_cycle_above_rpm: float | None
    """From this ω_v up (rpm) the law is not the every-cycle bound; None: it is over the whole range."""
    rotary_max_rpm: float
    vibration_max_rpm: float

    @classmethod
    def from_envelope(cls, envelope: EnvelopeOut, law: str | None = None) -> Curve:
        """The enforced curve of the service's ``/v1/envelope`` answer, or (``law``) that law's, without margin."""
        points = envelope.points
        if law is None:
            limits = tuple(p.limit_rotary_rpm for p in points)
        else:
            limits = tuple(p.laws_rotary_rpm.get(law) for p in points)
        return cls(
            omega_v_rpm=tuple(p.vibration_rpm for p in points),
            limit_rpm=limits,
            not_every_cycle_above_rpm=envelope.regime.above_vibration_rpm if envelope.regime else None,
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
        """Whether the law is the every-cycle bound at ``omega_v_rpm`` (the service's regime warning)."""
        above = self.not_every_cycle_above_rpm
        return above is None or (above > 0.0 and omega_v_rpm <= above)


def operating_points(status: StatusOut | None) -> tuple[tuple[float, float] | None, tuple[float, float] | None]:
    """The measured point and the target as (ω_v, ω_r) in rpm, each None while unknown."""
    point = target = None
    if status is not None and status.measured_vibration_rpm is not None and status.measured_rotary_rpm is not None:
        point = (status.measured_vibration_rpm, status.measured_rotary_rpm)
    if status is not None and status.target_vibration_rpm is not None and status.target_rotary_rpm is not None:
        target = (status.target_vibration_rpm, status.target_rotary_rpm)
    return point, target


Cells = tuple[tuple[str, ...], tuple[tuple[str, ...], ...]]
"""Braille rows, and the style of every cell of every row."""


def _dots(curve: Curve, cols: int, rows: int, y_max: float) -> list[list[int]]:
    """The braille dot bits of one curve, row by row."""
    dots_x, dots_y = 2 * cols, 4 * rows
    cells = [[0] * cols for _ in range(rows)]
    for dx in range(dots_x):
        frac = curve.limit_at(curve.vibration_max_rpm * dx / (dots_x - 1)) / y_max
        if frac > 1.0:
            continue  # above the top of the plot: not drawn at the edge, where it would look like a limit
        dy = dots_y - 1 - min(max(round(frac * (dots_y - 1)), 0), dots_y - 1)
        cells[dy // 4][dx // 2] |= _DOT_BITS[dy % 4][dx % 2]
    return cells


@functools.lru_cache(maxsize=16)
def _curve_cells(curve: Curve, others: tuple[tuple[Curve, str], ...], cols: int, rows: int, y_max: float) -> Cells:
    """The curves as braille rows with each cell's style: the others first, the enforced one over them.

    The enforced curve is green where its law is the every-cycle bound and yellow where it is not.
    """
    bits = [[0] * cols for _ in range(rows)]
    styles = [[""] * cols for _ in range(rows)]
    for other, style in others:
        for r, row in enumerate(_dots(other, cols, rows, y_max)):
            for c, cell in enumerate(row):
                if cell:
                    bits[r][c] |= cell
                    styles[r][c] = style
    column_style = ["green" if curve.every_cycle_at(curve.vibration_max_rpm * col / max(cols - 1, 1)) else "yellow"
                    for col in range(cols)]
    for r, row in enumerate(_dots(curve, cols, rows, y_max)):
        for c, cell in enumerate(row):
            if cell:
                bits[r][c] = cell  # the enforced curve alone in its cells: it must read clearly
                styles[r][c] = column_style[c]
    lines = tuple("".join(chr(BRAILLE_BASE + b) for b in row) for row in bits)
    return lines, tuple(tuple(row) for row in styles)


def render_plot(
    curve: Curve,
    width: int,
    height: int,
    point: tuple[float, float] | None = None,
    target: tuple[float, float] | None = None,
    others: tuple[tuple[Curve, str], ...] = (),
) -> Text:
    """The plot as ``height`` lines of ``width`` cells (axis labels included); points are (ω_v, ω_r) in rpm.

    ``others`` are further curves with their style, drawn under the enforced one.
    """
    y_max = curve.y_max_rpm(target[1] if target else 0.0, point[1] if point else 0.0)
    label_w = len(f"{y_max:.0f}") + 1
    cols, rows = max(width - label_w, 4), max(height - 1, 2)
    lines, styles = _curve_cells(curve, others, cols, rows, y_max)

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
        row_styles = list(styles[row])
        for (mark_row, col), (char, style) in marks.items():
            if mark_row == row:
                line[col], row_styles[col] = char, style
        text.append("".join(line) + "\n")
        run_start = 0
        for col in range(1, cols + 1):  # one span per run of equal style, not one per cell
            if col == cols or row_styles[col] != row_styles[run_start]:
                if row_styles[run_start]:
                    text.stylize(row_styles[run_start], start + run_start, start + col)
                run_start = col
    axis = f"0 ω_v rpm → {curve.vibration_max_rpm:.0f}"
    text.append(" " * label_w + axis.ljust(cols)[:cols], style="dim")
    return text


__all__ = ["Curve", "operating_points", "render_plot"]
