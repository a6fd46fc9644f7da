"""Argparse ``type=`` functions for numbers, shared by the command-line tools.

Each returns a number or raises ``argparse.ArgumentTypeError`` saying what was expected, so argparse reports
``argument --x: expected ..., got 'text'`` instead of ``invalid <function name> value``. NaN and infinities
are rejected: ``float()`` accepts them, and they break every later comparison.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable


def finite_number(text: str) -> float:
    """A finite float."""
    value = _float_or_nan(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def positive_number(text: str) -> float:
    """A finite float above zero."""
    value = _float_or_nan(text)
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def number_within(low: float, high: float, unit: str) -> Callable[[str], float]:
    """A ``type=`` function: a float in ``[low, high]`` (``unit`` names what it counts in the message)."""
    def within(text: str) -> float:
        value = _float_or_nan(text)
        if not low <= value <= high:  # also refuses NaN
            raise argparse.ArgumentTypeError(f"expected {unit} in [{low:g}, {high:g}], got {text!r}")
        return value
    return within


def non_negative_integer(text: str) -> int:
    """An integer >= 0 (a seed: numpy's generators take no negative one)."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}")
    return value


def _float_or_nan(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan
