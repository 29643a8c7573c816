"""Tables on stdout with headers never cut: the study's, and limits' cam comparison (issue 39, item 8).

Rich shortens a header that does not fit with an ellipsis; here every column is
at least as wide as the longest word of its header and of its cells, a header
wraps only between words, and columns that do not fit the width beside each
other go into a second part of the table, which repeats the key columns (the
point's number) so that each part reads alone.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from dataclasses import dataclass

from rich.cells import cell_len
from rich.console import Console
from rich.table import Table

_PADDING = 2
"""Cells per column for rich's default padding (one each side)."""
_RULE = 1
"""Cells per column for the vertical rule before it (and one more at the right edge)."""


@dataclass(frozen=True)
class Column:
    """A header and its cells, right-aligned."""

    header: str
    cells: tuple[str, ...]

    @property
    def least_width(self) -> int:
        """The width below which a word would be cut: the longest word of its header or cells."""
        words = [cell_len(w) for text in (self.header, *self.cells) for w in text.split()]
        return max(words, default=1)

    @property
    def natural_width(self) -> int:
        """The width at which its header and every cell fit on one line."""
        return max([cell_len(t) for t in (self.header, *self.cells)] + [self.least_width])


def _fit(columns: Sequence[Column], room: int) -> list[int]:
    """Widths from each column's least width, grown one cell at a time towards its natural width within ``room``."""
    widths = [c.least_width for c in columns]
    spare = room - sum(widths)
    while spare > 0:
        growing = [i for i, c in enumerate(columns) if widths[i] < c.natural_width]
        if not growing:
            break
        for i in growing[:spare]:
            widths[i] += 1
        spare -= min(spare, len(growing))
    return widths


def _parts(key: Sequence[Column], rest: Sequence[Column], width: int) -> list[list[Column]]:
    """The other columns in groups that fit beside the key columns, in order (at least one column a group)."""
    def cost(column: Column) -> int:
        return column.least_width + _PADDING + _RULE

    room = width - _RULE - sum(cost(c) for c in key)
    parts: list[list[Column]] = [[]]
    used = 0
    for column in rest:
        if parts[-1] and used + cost(column) > room:
            parts.append([])
            used = 0
        parts[-1].append(column)
        used += cost(column)
    return parts


def print_table(
    console: Console, title: str, columns: Sequence[Column], key_columns: int = 1, caption: str | None = None
) -> None:
    """Print ``columns`` as one table, or as several parts when they do not fit the console's width."""
    key, rest = list(columns[:key_columns]), list(columns[key_columns:])
    parts = _parts(key, rest, console.width) if rest else [[]]
    for n, part in enumerate(parts, start=1):
        shown = key + part
        room = console.width - _RULE - len(shown) * (_PADDING + _RULE)
        widths = _fit(shown, room)
        name = title if len(parts) == 1 else f"{title} (part {n} of {len(parts)})"
        lines = textwrap.wrap(name, console.width, break_long_words=False)
        note = "\n".join(textwrap.wrap(caption, console.width, break_long_words=False)) if caption else None
        table = Table(title="\n".join(lines), caption=note if n == len(parts) else None)
        for column, width in zip(shown, widths, strict=True):
            table.add_column(column.header, justify="right", width=width, overflow="fold")
        rows = len(shown[0].cells) if shown else 0
        for i in range(rows):
            table.add_row(*(c.cells[i] for c in shown))
        console.print(table)


__all__ = ["Column", "print_table"]
