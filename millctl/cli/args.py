"""Argument types shared by the command modules: numbers that say what was wrong with them."""

from __future__ import annotations

import argparse
import functools
import math
from collections.abc import Callable, Iterator, Sequence


def finite_float(text: str) -> float:
    """A finite number (argparse type); NaN and infinities are refused."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text} must be a finite number")
    return value


def nonnegative_float(text: str) -> float:
    """A finite number ≥ 0 (argparse type), e.g. a speed in rpm."""
    value = finite_float(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f"{text} must be ≥ 0")
    return value


def positive_int(text: str) -> int:
    """A whole number ≥ 1 (argparse type), e.g. a count of workers."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text} must be ≥ 1")
    return value


class LazyChoices(Sequence[str]):
    """An argparse ``choices`` list computed on first use, e.g. an enumeration's values from a heavy module.

    Building the parser then loads nothing; the values are read when an argument is checked or its help is
    shown. Give the argument a ``metavar`` (argparse would otherwise list the choices while building).
    """

    def __init__(self, load: Callable[[], Sequence[str]]) -> None:
        self._load = load

    @functools.cached_property
    def _values(self) -> tuple[str, ...]:
        return tuple(self._load())

    def __getitem__(self, index: int) -> str:  # type: ignore[override]
        return self._values[index]

    def __len__(self) -> int:
        return len(self._values)

    def __contains__(self, value: object) -> bool:
        return value in self._values

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __repr__(self) -> str:
        return repr(list(self._values))


__all__ = ["LazyChoices", "finite_float", "nonnegative_float", "positive_int"]
