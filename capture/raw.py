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
mid-write) and the writer cuts it off when it reopens the capture to append. Bytes after the last indexed
chunk (a kill between the data flush and the index line) have no receive time.
"""

from __future__ import annotations

import datetime as dt
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

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


def _cut_torn_line(path: Path) -> None:
    if not path.exists():
        return
    content = path.read_bytes()
    keep = content.rfind(b"\n") + 1
    if keep != len(content):
        with open(path, "r+b") as handle:
            handle.truncate(keep)


class CaptureIndexError(ValueError):
    """A malformed line in a ``.duml.idx`` file (not the torn last one)."""


@dataclass(frozen=True)
class ChunkIndex:
    """Receive times of a raw capture's chunks (numpy arrays, one entry per chunk, by offset)."""

    offsets: np.ndarray  # int64 stream offset of each chunk's first byte
    lengths: np.ndarray  # int64
    utc_unix_s: np.ndarray  # float64
    monotonic_s: np.ndarray  # float64

    def chunk_of(self, byte_offset: int) -> int | None:
        """Index of the chunk holding ``byte_offset``, or None when no chunk does."""
        i = int(np.searchsorted(self.offsets, byte_offset, side="right")) - 1
        if i < 0 or byte_offset >= self.offsets[i] + self.lengths[i]:
            return None
        return i

    def arrival_utc(self, byte_offset: int) -> dt.datetime | None:
        """When the byte at ``byte_offset`` arrived (UTC). A packet is complete when its LAST byte arrives."""
        i = self.chunk_of(byte_offset)
        return None if i is None else dt.datetime.fromtimestamp(float(self.utc_unix_s[i]), dt.timezone.utc)

    def arrival_monotonic(self, byte_offset: int) -> float | None:
        i = self.chunk_of(byte_offset)
        return None if i is None else float(self.monotonic_s[i])


def read_index(path: str | os.PathLike) -> ChunkIndex:
    """Parse a ``.duml.idx`` sidecar, tolerating a torn last line. Raises CaptureIndexError naming a bad line."""
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    lines = text.split("\n")[:-1]  # the piece after the last newline is torn (or empty)
    rows = []
    for number, line in enumerate(lines, start=1):
        if not line or line.startswith("#"):
            continue
        parts = line.split(",")
        try:
            if len(parts) != 4:
                raise ValueError(f"{len(parts)} fields")
            rows.append((int(parts[0]), int(parts[3]), float(parts[1]), float(parts[2])))
        except ValueError as error:
            raise CaptureIndexError(f"{path}:{number}: expected 'offset,utc_unix_s,monotonic_s,length', got {line!r} "
                              f"({error})") from None
    table = np.array(rows, dtype=np.float64).reshape(-1, 4)
    return ChunkIndex(table[:, 0].astype(np.int64), table[:, 1].astype(np.int64), table[:, 2], table[:, 3])


def read_capture_chunks(path: str | os.PathLike):
    """Yield ``(receive_time_utc | None, receive_time_monotonic | None, bytes)`` as the chunks were received.

    Without a sidecar (or past its end) the remaining bytes come as one chunk with no times.
    """
    path = Path(path)
    index = read_index(index_path(path)) if index_path(path).exists() else None
    with open(path, "rb") as handle:
        data = handle.read()
    position = 0
    if index is not None:
        for offset, length, utc, mono in zip(index.offsets.tolist(), index.lengths.tolist(),
                                             index.utc_unix_s.tolist(), index.monotonic_s.tolist()):
            if offset != position or offset + length > len(data):
                break
            yield dt.datetime.fromtimestamp(utc, dt.timezone.utc), mono, data[offset:offset + length]
            position = offset + length
    if position < len(data):
        yield None, None, data[position:]
