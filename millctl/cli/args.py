"""Argument types shared by the command modules: numbers that say what was wrong with them."""

from __future__ import annotations

import argparse
import math


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


__all__ = ["finite_float", "nonnegative_float", "positive_int"]
