"""Raw capture files: every byte kept, receive times per chunk, torn index lines survived."""

import datetime as dt

import pytest

from capture.raw import (CaptureIndexError, RawCaptureWriter, atomic_capture, index_path, read_capture_chunks,
                         read_index)

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
    chunks = list(read_capture_chunks(path))
    assert [c[2] for c in chunks] == [b"abc", b"defgh", b"i"]
    assert chunks[0][0] == T0 and chunks[1][0] == T0 + dt.timedelta(seconds=0.2)
    assert chunks[2][1] == pytest.approx(100.3)


def test_writer_creates_the_capture_folder(tmp_path):
    path = tmp_path / "new" / "folder" / "flight.duml"
    _write(path, [b"abc"])
    assert path.read_bytes() == b"abc" and read_index(index_path(path)).lengths.tolist() == [3]


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


def test_gap_left_by_a_kill_then_an_appending_rerun_is_passed_on_untimed(tmp_path):
    path = tmp_path / "flight.duml"
    _write(path, [b"abc"])
    with open(path, "ab") as handle:
        handle.write(b"de")  # killed between the data flush and its index line
    _write(path, [b"fgh", b"ij"])  # the rerun appends: its offsets continue after the unindexed bytes
    chunks = list(read_capture_chunks(path))
    assert [c[2] for c in chunks] == [b"abc", b"de", b"fgh", b"ij"]
    assert chunks[1][:2] == (None, None)
    assert chunks[2][0] == T0 and chunks[3][1] == pytest.approx(100.1)  # the rerun's chunks keep their times


@pytest.mark.parametrize("line, reason", [
    (b"3,nan,1.0,2\n", "times must be finite"),
    (b"3,1.0,inf,2\n", "times must be finite"),
    (b"3,1.0,1.0,-2\n", "length >= 1"),
    (b"-3,1.0,1.0,2\n", "offset must be >= 0"),
    (b"1,1.0,1.0,2\n", "starts before the previous one ends at offset 3"),
    (b"3,1.0,1.0,\xff2\n", "expected UTF-8 text .* byte 0xff at column 11"),
])
def test_bad_index_line_names_the_file_and_line(tmp_path, line, reason):
    path = tmp_path / "flight.duml"
    _write(path, [b"abc"])
    with open(index_path(path), "ab") as handle:
        handle.write(line)
    with pytest.raises(CaptureIndexError, match=rf"flight.duml.idx:3: .*{reason}"):
        read_index(index_path(path))


def test_index_running_past_the_data_is_an_error(tmp_path):
    path = tmp_path / "flight.duml"
    _write(path, [b"abc", b"de"])
    path.write_bytes(b"abcd")  # the data lost its last byte, the index did not
    with pytest.raises(CaptureIndexError, match=r"flight.duml.idx:3: .*the chunk ends at byte 5, past the end of "
                                                 r"the data \(4 bytes\)"):
        list(read_capture_chunks(path))


@pytest.mark.parametrize("length", ["10000000000000000000000", "9007199254740993"])
def test_index_line_with_a_huge_length_names_the_file_and_line(tmp_path, length):
    path = tmp_path / "flight.duml"
    _write(path, [b"abc"])
    with open(index_path(path), "a") as handle:
        handle.write(f"3,1.0,1.0,{length}\n")
    with pytest.raises(CaptureIndexError, match=rf"flight.duml.idx:3: .*{length}.* past the end of the data"):
        read_index(index_path(path))
    with pytest.raises(CaptureIndexError, match=r"flight.duml.idx:3: .* past the end of the data \(3 bytes\)"):
        list(read_capture_chunks(path))


def test_atomic_capture_replaces_both_files_or_neither(tmp_path):
    path = tmp_path / "sim" / "flight.duml"
    with atomic_capture(path) as writer:
        writer.append(T0, 1.0, b"abc")
    assert path.read_bytes() == b"abc" and read_index(index_path(path)).lengths.tolist() == [3]
    with pytest.raises(RuntimeError), atomic_capture(path) as writer:
        writer.append(T0, 2.0, b"XYZW")
        raise RuntimeError("the simulation failed")
    assert [c[2] for c in read_capture_chunks(path)] == [b"abc"]  # the old capture, whole
    assert sorted(p.name for p in path.parent.iterdir()) == ["flight.duml", "flight.duml.idx"]
