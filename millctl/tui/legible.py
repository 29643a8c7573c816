"""Monochrome that stays readable: what the TUI shows under ``NO_COLOR``.

Textual's own NO_COLOR filter maps every colour to the grey of the same
luminance, so pairs that differ only in hue collapse: bold red "OFFLINE" on a
dark bar became grey 237 on grey 235 (1.3:1), panel borders 1.6:1. This
filter does the same greyscale mapping, then lifts every foreground that is
below :data:`MIN_CONTRAST` against its background to the nearest grey that
reaches it (WCAG 2 contrast ratio), and drops ``dim``, which would halve it
again. Emphasis that colour carried elsewhere (trips, refusals, OFFLINE) is
also bold or reversed in the TUI's styles, so it survives.
"""

from __future__ import annotations

from functools import lru_cache

from rich.color import Color as RichColor
from rich.segment import Segment
from rich.style import Style
from textual.color import Color
from textual.filter import LineFilter, monochrome_style

MIN_CONTRAST = 4.5
"""WCAG 2 AA contrast ratio for normal text."""


def luminance(rgb: tuple[int, int, int]) -> float:
    """WCAG 2 relative luminance of an sRGB colour (0 black … 1 white)."""

    def channel(value: int) -> float:
        c = value / 255.0
        return c / 12.92 if c <= 0.03928 else ((c + 0.055) / 1.055) ** 2.4

    r, g, b = rgb
    return 0.2126 * channel(r) + 0.7152 * channel(g) + 0.0722 * channel(b)


def contrast(a: tuple[int, int, int], b: tuple[int, int, int]) -> float:
    """WCAG 2 contrast ratio of two colours (1 … 21)."""
    high, low = sorted((luminance(a), luminance(b)), reverse=True)
    return (high + 0.05) / (low + 0.05)


@lru_cache(maxsize=1024)
def legible_grey(foreground: tuple[int, int, int], background: tuple[int, int, int]) -> tuple[int, int, int]:
    """``foreground`` if it reaches MIN_CONTRAST on ``background``, else the nearest grey that does."""
    if contrast(foreground, background) >= MIN_CONTRAST:
        return foreground
    lighter = luminance(background) < 0.18  # on a dark background go lighter, on a light one darker
    level = foreground[0]
    for _ in range(256):
        level = min(level + 1, 255) if lighter else max(level - 1, 0)
        if contrast((level, level, level), background) >= MIN_CONTRAST or level in (0, 255):
            break
    return (level, level, level)


@lru_cache(maxsize=4096)
def legible_style(style: Style) -> Style:
    """The monochrome of ``style``, without dim, its foreground lifted to MIN_CONTRAST."""
    mono = monochrome_style(style) + Style(dim=False)
    fg, bg = mono.color, mono.bgcolor
    if fg is None or bg is None:
        return mono
    fg_rgb, bg_rgb = tuple(fg.get_truecolor()), tuple(bg.get_truecolor())
    lifted = legible_grey(fg_rgb, bg_rgb)
    if lifted == fg_rgb:
        return mono
    return mono + Style(color=RichColor.from_rgb(*lifted))


class LegibleMonochrome(LineFilter):
    """Greyscale with every foreground at least MIN_CONTRAST against its background, and no dim text."""

    def apply(self, segments: list[Segment], background: Color) -> list[Segment]:
        """Transform a line's segments."""
        return [Segment(text, None if style is None else legible_style(style), None) for text, style, _ in segments]


__all__ = ["MIN_CONTRAST", "LegibleMonochrome", "contrast", "legible_grey", "legible_style", "luminance"]
