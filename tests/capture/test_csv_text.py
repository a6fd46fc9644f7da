"""Numbers written a column at a time are what ``csv.writer`` writes for the same Python values: ``repr`` for
floats, ``str`` for integers, ``0``/``1`` for bools, on both sides of every shortcut (the digit tables, whole
tenths, repr's switch to exponents)."""

import numpy as np
import pytest

from capture.csv_text import join_cells, number_text, strings_text

pytestmark = pytest.mark.filterwarnings("error")  # NaN, inf and overflow pass silently (decode's stderr stays clean)


def _texts(values: np.ndarray) -> list[str]:
    data, lengths = join_cells([b"<", number_text(values), b">\n"], len(values))
    assert lengths.tolist() == [len(line) for line in data.decode().splitlines(keepends=True)]
    return [line[1:-2] for line in data.decode().splitlines(keepends=True)]


RNG = np.random.default_rng(7)
FLOAT_CASES = {
    "tenths below 1000 (the table)": np.arange(-9999, 10000) / 10,
    "tenths up to 2**21": np.arange(-2 ** 21, 2 ** 21, 37) / 10,
    "tenths near 2**50": RNG.integers(-2 ** 50, 2 ** 50, 20_000) / 10,
    "small tenths beside large ones": np.concatenate([np.arange(-12, 13) / 10, [123456.7]]),
    "degrees": np.degrees(RNG.uniform(-np.pi, np.pi, 20_000)),
    "f32 altitudes": RNG.normal(0, 300, 20_000).astype(np.float32).astype(np.float64) / 10,
    "any magnitude": RNG.normal(size=20_000) * 10.0 ** RNG.integers(-320, 308, 20_000),
    "special": np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 1e16, 9999999999999998.0, 1e15 + 0.5, 1e-4, 1e-5,
                         0.1 + 0.2, 2.0 ** 50 / 10, -(2.0 ** 50) / 10, 5e-324, np.finfo(float).max]),
}


@pytest.mark.parametrize("case", FLOAT_CASES)
def test_floats_are_written_as_repr(case):
    values = FLOAT_CASES[case]
    assert _texts(values) == list(map(repr, values.tolist()))


@pytest.mark.parametrize("dtype", ["i1", "u1", "<i2", "<u2", "<i4", "<u4", "<i8"])
def test_integers_are_written_as_str(dtype):
    info = np.iinfo(dtype)
    edges = [info.min + (dtype == "<i8"), info.max, 0, 1, 9, 10, 99, 100, 9999, 10000, 99999, 100000]
    values = np.concatenate([RNG.integers(info.min + 1, info.max, 20_000, endpoint=True),
                             [e for e in edges if info.min <= e <= info.max]]).astype(dtype)
    assert _texts(values) == list(map(str, values.tolist()))
    small = values[np.abs(values.astype(np.int64)) < 10_000]
    assert _texts(small) == list(map(str, small.tolist()))


def test_bools_are_written_as_0_or_1_and_empty_columns_are_empty():
    flags = RNG.random(100) < 0.5
    assert _texts(flags) == [str(int(f)) for f in flags]
    for empty in (np.zeros(0), np.zeros(0, np.int16), np.zeros(0, bool)):
        assert join_cells([b"x", number_text(empty)], 0)[0] == b""


def test_cells_join_into_lines_with_texts_and_fixed_bytes():
    text, lengths = join_cells([strings_text(["2024", "", "x"]), b",", number_text(np.array([-1.5, 0.0, 30.0])),
                                b",\r\n"], 3)
    assert text == b"2024,-1.5,\r\n,0.0,\r\nx,30.0,\r\n" and lengths.tolist() == [12, 7, 9]


def test_what_has_no_text_is_refused():
    with pytest.raises(TypeError, match="uint64"):
        number_text(np.zeros(2, np.uint64))
    with pytest.raises(ValueError, match="-2\\*\\*63"):
        number_text(np.array([np.iinfo(np.int64).min]))
