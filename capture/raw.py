"""Raw capture files: the bytes exactly as received, plus a sidecar of receive times.

``NAME.duml``: the received bytes, appended and flushed chunk by chunk, before any parsing (a parser bug or a
crash never loses data). This is the one writer in the project that does not write-then-rename: a live
capture must survive ``kill -9`` at any moment with everything received so far on disk.

``NAME.duml.idx``: UTF-8 text, one line per received chunk, written after that chunk's bytes were flushed::

    # aerostereo-duml-idx/1 offset,utc_unix_s,monotonic_s,length
    0,1703104478.123456,8123.000123456,64
    64,1703104478.133501,8123.010168000,17

- ``offset``: stream offset of the chunk's first byte in ``NAME.duml``; ``length`` its size in bytes;
- ``utc_unix_s``: receive time, seconds since 1970-01-01 UTC (microseconds);
- ``monotonic_s``: receive time on the host's monotonic clock (seconds, nanoseconds), for intervals.

A line is valid only if it ends in a newline and has four fields; a reader ignores a torn last line (a kill
mid-write) and the writer cuts it off when it reopens the capture to append. Bytes that no line covers (a kill
between the data flush and the index line) have no receive time; an appending rerun leaves them as a gap
between the offsets of two lines, which a reader passes on untimed.
"""

from __future__ import annotations

import datetime as dt
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cliutil.atomic import atomic_path

IDX_HEADER = "# aerostereo-duml-idx/1 offset,utc_unix_s,monotonic_s,length\n"


def index_path(capture_path: str | os.PathLike) -> Path:
    return Path(f"{os.fspath(capture_path)}.idx")


class RawCaptureWriter:
    """Append received chunks to ``NAME.duml`` and their receive times to ``NAME.duml.idx``.

    Opening an existing capture appends to it (offsets continue), after cutting a torn last index line.
    ``fsync=True`` also forces every chunk to the disk (survives power loss, costs a sync per chunk).
    """

    def __init__(self, path: str | os.PathLike, fsync: bool = False) -> None:
        self.path = Path(path)
        self.fsync = fsync
        self.path.parent.mkdir(parents=True, exist_ok=True)
        _cut_torn_line(index_path(self.path))
        self._data = open(self.path, "ab")
        self._index = open(index_path(self.path), "a", encoding="utf-8", newline="\n")
        self.offset = self._data.tell()
        if self._index.tell() == 0:
            self._index.write(IDX_HEADER)
            self._index.flush()

    def append(self, receive_time_utc: dt.datetime, receive_time_monotonic: float, data: bytes) -> int:
        """Write ``data`` and its index line; return the stream offset of its first byte."""
        if not data:
            return self.offset
        offset = self.offset
        self._data.write(data)
        self._flush(self._data)
        self._index.write(f"{offset},{receive_time_utc.timestamp():.6f},{receive_time_monotonic:.9f},{len(data)}\n")
        self._flush(self._index)
        self.offset += len(data)
        return offset

    def _flush(self, handle) -> None:
        handle.flush()
        if self.fsync:
            os.fsync(handle.fileno())

    def close(self) -> None:
        self._data.close()
        self._index.close()

    def __enter__(self) -> "RawCaptureWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@contextmanager
def atomic_capture(path: str | os.PathLike) -> Iterator[RawCaptureWriter]:
    """A :class:`RawCaptureWriter` on temporary files beside ``path``, for a capture written in one go (a
    simulation, a conversion): on success ``NAME.duml`` and ``NAME.duml.idx`` replace any old ones, on error
    neither is touched and the temporaries are removed. A live recording appends with the writer itself."""
    with atomic_path(path) as data_tmp, atomic_path(index_path(path)) as index_tmp:
        try:
            with RawCaptureWriter(data_tmp) as writer:
                yield writer
            index_path(data_tmp).replace(index_tmp)
        finally:
            index_path(data_tmp).unlink(missing_ok=True)


def _cut_torn_line(path: Path) -> None:
    if not path.exists():
        return
    content = path.read_bytes()
    keep = content.rfind(b"\n") + 1
    if keep != len(content):
        with open(path, "r+b") as handle:
            handle.truncate(keep)


class CaptureIndexError(ValueError):
    """A malformed line in a ``.duml.idx`` file (not the torn last one), or chunks that do not fit the data."""


@dataclass(frozen=True)
class ChunkIndex:
    """Receive times of a raw capture's chunks (numpy arrays, one entry per chunk, by offset)."""

    offsets: np.ndarray  # int64 stream offset of each chunk's first byte
    lengths: np.ndarray  # int64
    utc_unix_s: np.ndarray  # float64
    monotonic_s: np.ndarray  # float64


_IDX_FIELDS = "'offset,utc_unix_s,monotonic_s,length'"


def read_index(path: str | os.PathLike, data_bytes: int | None = None) -> ChunkIndex:
    """Parse a ``.duml.idx`` sidecar, tolerating a torn last line.

    Raises CaptureIndexError naming the file and line for a line that is not UTF-8, has the wrong fields, a
    time that is not finite, a negative offset, a length below 1, a chunk that starts before the previous one
    ends, or (``data_bytes`` given: the size of the capture's data) a chunk that runs past the data. Gaps between
    chunks are allowed (bytes whose index line a kill cut off, then an appending rerun).
    """
    path = Path(path)
    lines = path.read_bytes().split(b"\n")[:-1]  # the piece after the last newline is torn (or empty)
    rows = []
    chunks_end = 0
    for number, raw_line in enumerate(lines, start=1):
        try:
            line = raw_line.decode("utf-8")
        except UnicodeDecodeError as error:
            raise CaptureIndexError(f"{path}:{number}: expected UTF-8 text {_IDX_FIELDS}, got byte "
                                    f"0x{raw_line[error.start]:02x} at column {error.start + 1}") from None
        if not line or line.startswith("#"):
            continue
        try:
            row = _index_row(line, chunks_end, _MAX_STREAM_BYTES if data_bytes is None else data_bytes)
        except ValueError as error:
            raise CaptureIndexError(f"{path}:{number}: expected {_IDX_FIELDS}, got {line!r} ({error})") from None
        rows.append(row)
        chunks_end = row[0] + row[1]
    offsets, lengths, utc, mono = zip(*rows) if rows else ((),) * 4
    return ChunkIndex(np.array(offsets, dtype=np.int64), np.array(lengths, dtype=np.int64),
                      np.array(utc, dtype=np.float64), np.array(mono, dtype=np.float64))


_MAX_STREAM_BYTES = 2 ** 53  # offsets and lengths stay exact in int64 and float64 below this


def _index_row(line: str, previous_end: int, data_bytes: int) -> tuple[int, int, float, float]:
    """``(offset, length, utc_unix_s, monotonic_s)`` of one index line; ValueError saying what is wrong."""
    parts = line.split(",")
    if len(parts) != 4:
        raise ValueError(f"{len(parts)} fields")
    offset, length, utc, mono = int(parts[0]), int(parts[3]), float(parts[1]), float(parts[2])
    if not (np.isfinite(utc) and np.isfinite(mono)):
        raise ValueError("times must be finite")
    if offset < 0 or length < 1:
        raise ValueError("offset must be >= 0 and length >= 1")
    if offset < previous_end:
        raise ValueError(f"the chunk starts before the previous one ends at offset {previous_end}")
    if offset + length > data_bytes:
        raise ValueError(f"the chunk ends at byte {offset + length}, past the end of the data ({data_bytes} bytes)")
    return offset, length, utc, mono


def read_capture_chunks(path: str | os.PathLike):
    """Yield ``(receive_time_utc | None, receive_time_monotonic | None, bytes)`` as the chunks were received.

    Bytes no index line covers (no sidecar, a gap a kill left before an appending rerun, or past the last
    line) come as chunks with no times, in stream order. CaptureIndexError (naming the ``.idx`` line) when an
    indexed chunk runs past the end of the data.
    """
    path = Path(path)
    with open(path, "rb") as handle:
        data = handle.read()
    index = (read_index(index_path(path), len(data)) if index_path(path).exists()
             else ChunkIndex(*[np.empty(0)] * 4))
    position = 0
    for offset, length, utc, mono in zip(index.offsets.tolist(), index.lengths.tolist(),
                                         index.utc_unix_s.tolist(), index.monotonic_s.tolist()):
        if offset > position:
            yield None, None, data[position:offset]
        yield dt.datetime.fromtimestamp(utc, dt.timezone.utc), mono, data[offset:offset + length]
        position = offset + length
    if position < len(data):
        yield None, None, data[position:]
