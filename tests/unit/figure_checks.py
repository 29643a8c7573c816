"""What makes a figure stand alone in a paper, checked on its artists (not its pixels): shared by the figure tests."""

from __future__ import annotations

import re
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text

from millctl.figstyle import COLUMN_WIDTH_IN, MIN_FONT_PT

UNIT = re.compile(r"\([^()]*(\([^()]*\))?[^()]*\)\s*(,.*)?$", re.S)
"""A label ending in its unit in parentheses, perhaps followed by a remark (``…(W), higher is better``)."""
LEGEND_GAP_IN = 0.35
"""Farthest a legend may sit below its panel's x label (in): next to the panel, not far below it."""


def _renderer(fig: Figure) -> Any:
    canvas = FigureCanvasAgg(fig)
    fig.draw_without_rendering()
    return canvas.get_renderer()  # type: ignore[no-untyped-call]


def legible_at_one_column(fig: Figure, name: str) -> None:
    """One column wide, every text ≥ 7 pt and inside the figure, every axis labelled with its unit, a title."""
    renderer = _renderer(fig)
    assert fig.get_figwidth() <= COLUMN_WIDTH_IN + 1e-9, (name, fig.get_figwidth())
    for text in fig.findobj(Text):
        if text.get_visible() and text.get_text().strip():
            assert float(text.get_fontsize()) >= MIN_FONT_PT, (name, text.get_text(), text.get_fontsize())
    drawn = fig.get_tightbbox(renderer)  # in inches: everything drawn, tick labels in view only
    assert drawn is not None
    assert drawn.x0 >= -0.01 and drawn.x1 <= fig.get_figwidth() + 0.01, (name, drawn)  # nothing cut at the edge
    assert drawn.y0 >= -0.01 and drawn.y1 <= fig.get_figheight() + 0.01, (name, drawn)
    for ax in fig.axes:
        colorbar = getattr(ax, "_colorbar", None) is not None
        labels = [ax.get_ylabel()] if colorbar else [ax.get_xlabel(), ax.get_ylabel()]
        for label in labels:
            assert UNIT.search(" ".join(label.split())), (name, label)
    suptitle = fig.get_suptitle()
    assert suptitle or all(ax.get_title() for ax in fig.axes if getattr(ax, "_colorbar", None) is None), name


def legends_beside_the_data(fig: Figure) -> None:
    """Every legend off every panel's data area, and right under the x label of the panel above it."""
    renderer = _renderer(fig)
    legends = [*fig.legends, *(legend for ax in fig.axes if (legend := ax.get_legend()) is not None)]
    assert legends
    for legend in legends:
        box = legend.get_window_extent(renderer)
        for ax in fig.axes:
            data = ax.get_window_extent(renderer)
            assert not box.shrunk(0.99, 0.99).overlaps(data), (legend, data)  # hides no data
        above = [ax.get_tightbbox(renderer, bbox_extra_artists=[]) for ax in fig.axes]
        gaps = [b.y0 - box.y1 for b in above if b is not None and b.y0 >= box.y1 - 1.0]
        assert gaps and min(gaps) <= LEGEND_GAP_IN * fig.dpi, (gaps, fig.dpi)  # next to the panel, not far below


__all__ = ["legends_beside_the_data", "legible_at_one_column"]
