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
_LIMB_TEXTS = np.concatenate([_PADDED_LIMBS, _LIMBS, np.zeros_like(_LIMBS)])  # the three ways a limb is written
_TENTHS_LIMBS = np.hstack([np.zeros((_LIMB, 3), np.uint8), _LIMBS[np.arange(_LIMB) // 10, 1:],
                           np.full((_LIMB, 1), _POINT, np.uint8), _PADDED_LIMBS[:, 3:]])  # i / 10, 8 bytes a row


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


def _digits(magnitudes: np.ndarray) -> np.ndarray:
    """Decimal digits of non-negative int64 ``magnitudes``, NUL-padded on the left to a common width: four digits
    at a time from a table, zero-padded after the first digit, NUL-padded or empty before it."""
    largest = int(magnitudes.max()) if len(magnitudes) else 0
    width = len(str(largest))
    if largest < _LIMB:
        return _gathered(_LIMBS, magnitudes, width)
    count = -(-width // 4)
    rows = np.empty((len(magnitudes), count), dtype=np.int64)  # limbs, most significant first, as table rows
    started = np.zeros(len(magnitudes), dtype=bool)  # a digit was written in an earlier limb
    for position, power in enumerate(range(count - 1, -1, -1)):
        limb = magnitudes // _LIMB ** power % _LIMB
        digits_here = (limb != 0) | (power == 0)
        rows[:, position] = limb + _LIMB * np.where(started, 0, np.where(digits_here, 1, 2))
        started |= digits_here
    return _gathered(_LIMB_TEXTS, rows, width)


def _tenths_digits(magnitudes: np.ndarray) -> np.ndarray:
    """``magnitudes / 10`` with one decimal (``0.5``, ``12.0``), NUL-padded on the left to a common width."""
    largest = int(magnitudes.max()) if len(magnitudes) else 0
    if largest < _LIMB:
        return _gathered(_TENTHS_LIMBS, magnitudes, len(str(largest // 10)) + 2)
    point = np.full((len(magnitudes), 1), _POINT, np.uint8)
    return np.hstack([_digits(magnitudes // 10), point, (magnitudes % 10 + _ZERO).astype(np.uint8)[:, None]])


def _gathered(table: np.ndarray, rows: np.ndarray, width: int) -> np.ndarray:
    """The last ``width`` bytes of ``table``'s rows ``rows`` ((n,) or (n, k) of them, side by side): gathered as
    one 4- or 8-byte word per row, much faster than rows of bytes."""
    words = table.view(np.uint32 if table.shape[1] == 4 else np.uint64)[:, 0][rows]
    text = words.view(np.uint8).reshape(len(rows), table.shape[1] * int(np.prod(rows.shape[1:])))
    return text[:, text.shape[1] - width:]


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
