"""What every figure of millctl shares so that it stands alone in a paper: one column wide, legible there.

A journal column is about 3.4 in wide; a figure drawn at that width with fonts of
7 pt or more needs no scaling to be read in print (issue 39, item 9). The study
figures (:mod:`millctl.studies.figures`) and ``millctl limits --plot``
(:mod:`millctl.cli.limits_plot`) are drawn under :data:`RC` and wrap long
legend entries and titles with :func:`wrap`. Nothing here imports matplotlib.
"""

from __future__ import annotations

import textwrap

COLUMN_WIDTH_IN = 3.4
"""Width of one journal column (in), the width every figure is drawn at."""
MIN_FONT_PT = 7.0
"""The smallest font a figure may use at :data:`COLUMN_WIDTH_IN` (pt)."""

RC: dict[str, float | str] = {
    "font.size": 7.5,
    "axes.titlesize": 8.0,
    "axes.labelsize": 7.5,
    "xtick.labelsize": 7.0,
    "ytick.labelsize": 7.0,
    "legend.fontsize": 7.0,
    "figure.titlesize": 8.5,
    "lines.markersize": 4.0,
}
"""matplotlib settings for every figure (``matplotlib.rc_context(RC)``): fonts no smaller than :data:`MIN_FONT_PT`."""

LEGEND_CHARS = 52
"""Characters a legend line holds beside its handle at 7 pt in one column."""
TITLE_CHARS = 50
"""Characters a title line holds at 8 pt in one column."""


def wrap(text: str, width: int) -> str:
    """``text`` broken between words into lines of at most ``width`` characters (a word longer stays whole)."""
    return "\n".join(textwrap.wrap(text, width, break_long_words=False, break_on_hyphens=False)) or text


__all__ = ["COLUMN_WIDTH_IN", "LEGEND_CHARS", "MIN_FONT_PT", "RC", "TITLE_CHARS", "wrap"]
