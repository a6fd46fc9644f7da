"""Numbers as CSV text for many rows at once, byte for byte what ``csv.writer`` writes for the Python values.

Text is built as uint8 arrays of shape (rows, width), one row's text per array row, padded with NUL bytes
(which no number's text holds); :func:`join_cells` lays cells side by side and drops the padding. Integers and
bools are written with numpy digit arithmetic; floats that are a whole number of tenths (everything DJI sends
in 0.1 units) too, since ``repr`` of such a float is its one-decimal text; other floats through ``repr``.
"""

from __future__ import annotations

import numpy as np

_ZERO, _MINUS, _POINT = ord("0"), ord("-"), ord(".")
_EXACT_TENTHS_LIMIT = 2.0 ** 50  # tenths counts below this are exact in float64 and far from repr's 1e16 switch
_LIMB = 10_000  # digits are looked up four at a time
_FOUR_PLACES = 10 ** np.arange(3, -1, -1)
_PADDED_LIMBS = (np.arange(_LIMB)[:, None] // _FOUR_PLACES % 10 + _ZERO).astype(np.uint8)  # i < 10000 as "%04d"
_LIMBS = np.where((np.arange(_LIMB)[:, None] >= _FOUR_PLACES) | (_FOUR_PLACES == 1), _PADDED_LIMBS,
                  0).astype(np.uint8)  # i < 10000 as "%d", NUL-padded on the left
_TENTHS_LIMBS = np.hstack([_LIMBS[np.arange(_LIMB) // 10, 1:], np.full((_LIMB, 1), _POINT),
                           _PADDED_LIMBS[:, 3:]]).astype(np.uint8)  # i < 10000 as i / 10 with one decimal


def number_text(values: np.ndarray) -> np.ndarray:
    """CSV text of a bool, integer (up to int64) or float array: ``0``/``1`` for bools (as csv writes
    ``int(bool)``), the decimal digits for integers, ``repr`` for floats."""
    if values.dtype == np.bool_:
        return np.where(values, _ZERO + 1, _ZERO).astype(np.uint8)[:, None]
    if values.dtype.kind in "iu" and values.dtype != np.uint64:
        magnitudes = np.abs(values.astype(np.int64))
        if len(magnitudes) and magnitudes.min() < 0:
            raise ValueError("-2**63 has no int64 magnitude")
        return _signed(values < 0, _digits(magnitudes))
    if values.dtype.kind == "f":
        return _float_text(values.astype(np.float64))
    raise TypeError(f"no CSV text for {values.dtype} values")


def strings_text(texts: list[str]) -> np.ndarray:
    """ASCII ``texts`` as a (rows, width) uint8 array (NUL-padded)."""
    array = np.array(texts, dtype="S")
    return array.view(np.uint8).reshape(len(texts), array.itemsize)


def join_cells(cells: list, rows: int) -> tuple[bytes, np.ndarray]:
    """Lines made of ``cells`` side by side, each either bytes (the same in every line) or a (rows, width) text
    array: ``(all lines' bytes, each line's length)``."""
    widths = [len(cell) if isinstance(cell, bytes) else cell.shape[1] for cell in cells]
    matrix = np.zeros((rows, sum(widths)), dtype=np.uint8)
    position = 0
    for cell, width in zip(cells, widths):
        matrix[:, position:position + width] = np.frombuffer(cell, np.uint8) if isinstance(cell, bytes) else cell
        position += width
    return matrix.tobytes().translate(None, b"\0"), np.count_nonzero(matrix, axis=1)


_POWERS_OF_TEN = 10 ** np.arange(1, 19, dtype=np.int64)


def _digits(magnitudes: np.ndarray, minimum: int = 1) -> np.ndarray:
    """Decimal digits of non-negative int64 ``magnitudes`` (at least ``minimum``, zero-padded), NUL-padded on
    the left to a common width."""
    largest = int(magnitudes.max()) if len(magnitudes) else 0
    width = max(len(str(largest)), minimum)
    if largest < _LIMB and minimum == 1:
        return _LIMBS[:, _LIMBS.shape[1] - width:][magnitudes]
    text = np.hstack([_PADDED_LIMBS[magnitudes // _LIMB ** i % _LIMB] for i in range((width - 1) // 4, -1, -1)])
    text = text[:, -width:]
    count = np.maximum(np.searchsorted(_POWERS_OF_TEN, magnitudes, side="right") + 1, minimum)
    text[np.arange(width) < (width - count)[:, None]] = 0
    return text


def _tenths_digits(magnitudes: np.ndarray) -> np.ndarray:
    """``magnitudes / 10`` with one decimal (``0.5``, ``12.0``), NUL-padded on the left to a common width."""
    largest = int(magnitudes.max()) if len(magnitudes) else 0
    if largest < _LIMB:
        width = len(str(largest // 10)) + 2
        return _TENTHS_LIMBS[:, _TENTHS_LIMBS.shape[1] - width:][magnitudes]
    digits = _digits(magnitudes, minimum=2)
    point = np.full((len(digits), 1), _POINT, np.uint8)
    return np.hstack([digits[:, :-1], point, digits[:, -1:]])


def _signed(negative: np.ndarray, text: np.ndarray) -> np.ndarray:
    """``text`` with a leading ``-`` where ``negative``."""
    return np.hstack([np.where(negative, _MINUS, 0).astype(np.uint8)[:, None], text])


def _float_text(values: np.ndarray) -> np.ndarray:
    """``repr`` of each float64, as text: whole tenths with digit arithmetic, the others through ``repr``."""
    with np.errstate(over="ignore"):  # past 1.8e307: inf, never exact
        tenths = np.round(values * 10)
    exact = (np.abs(tenths) < _EXACT_TENTHS_LIMIT) & (tenths / 10 == values)  # NaN and inf are never exact
    exact_text = _signed(np.signbit(values[exact]), _tenths_digits(np.abs(tenths[exact]).astype(np.int64)))
    other_text = strings_text(list(map(repr, values[~exact].tolist())))
    text = np.zeros((len(values), max(exact_text.shape[1], other_text.shape[1])), dtype=np.uint8)
    text[exact, :exact_text.shape[1]] = exact_text
    text[~exact, :other_text.shape[1]] = other_text
    return text
