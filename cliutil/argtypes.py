"""Argparse ``type=`` functions for numbers, shared by the command-line tools.

Each returns a float or raises ``argparse.ArgumentTypeError`` saying what was expected, so argparse reports
``argument --x: expected ..., got 'text'`` instead of ``invalid <function name> value``. NaN and infinities
are rejected: ``float()`` accepts them, and they break every later comparison.
"""

from __future__ import annotations

import argparse
import math


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


def _float_or_nan(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan
