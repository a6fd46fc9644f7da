"""Raw capture files: every byte kept, receive times per chunk, torn index lines survived."""

import datetime as dt

import pytest

from capture.raw import CaptureIndexError, RawCaptureWriter, index_path, read_capture_chunks, read_index

T0 = dt.datetime(2024, 5, 1, 12, 0, 0, tzinfo=dt.timezone.utc)


def _write(path, chunks):
    with RawCaptureWriter(path) as writer:
        for i, data in enumerate(chunks):
            writer.append(T0 + dt.timedelta(seconds=i / 10), 100.0 + i / 10, data)


def test_bytes_and_arrival_times(tmp_path):
    path = tmp_path / "flight.duml"
    _write(path, [b"abc", b"", b"defgh", b"i"])
    assert path.read_bytes() == b"abcdefghi"
    index = read_index(index_path(path))
    assert index.offsets.tolist() == [0, 3, 8] and index.lengths.tolist() == [3, 5, 1]
    assert index.arrival_utc(0) == T0 and index.arrival_utc(2) == T0
    assert index.arrival_utc(3) == T0 + dt.timedelta(seconds=0.2)
    assert index.arrival_monotonic(8) == pytest.approx(100.3)
    assert index.arrival_utc(9) is None and index.arrival_utc(-1) is None


def test_reopening_appends_and_cuts_a_torn_index_line(tmp_path):
    path = tmp_path / "flight.duml"
    _write(path, [b"abc"])
    with open(index_path(path), "a") as handle:
        handle.write("3,17145648")  # killed mid-line
    assert read_index(index_path(path)).offsets.tolist() == [0]  # the reader ignores the torn line
    _write(path, [b"XY"])
    index = read_index(index_path(path))
    assert path.read_bytes() == b"abcXY" and index.offsets.tolist() == [0, 3]
    assert [chunk[2] for chunk in read_capture_chunks(path)] == [b"abc", b"XY"]


def test_bytes_without_index_lines_are_still_read(tmp_path):
    path = tmp_path / "flight.duml"
    _write(path, [b"abc", b"de"])
    with open(path, "ab") as handle:
        handle.write(b"fg")  # killed between the data flush and its index line
    chunks = list(read_capture_chunks(path))
    assert b"".join(c[2] for c in chunks) == b"abcdefg"
    assert chunks[-1] == (None, None, b"fg")


def test_malformed_index_line_names_the_line(tmp_path):
    path = tmp_path / "flight.duml"
    _write(path, [b"abc"])
    with open(index_path(path), "a") as handle:
        handle.write("3,not-a-time,1.0,2\n")
    with pytest.raises(CaptureIndexError, match=r"flight.duml.idx:3:"):
        read_index(index_path(path))
