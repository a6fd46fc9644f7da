"""EXIF blocks (a TIFF structure after ``Exif\\0\\0``) written with explicit TIFF types, and the byte-level edit that
gives an existing block a new GPS IFD without moving anything else.

* :func:`tiff_bytes` lays out IFD0 and its sub-IFDs from :class:`Entry` values, each with the TIFF type the EXIF
  standard (CIPA DC-008) gives its tag (``UNDEFINED`` for ComponentsConfiguration, ``SRATIONAL`` for
  ExposureBiasValue, ...), which a writer that infers types from Python values (Pillow) cannot be told.
* :func:`with_gps_ifd` appends a GPS IFD to an existing TIFF block and repoints IFD0 at it. Every other byte keeps
  its place, so the offsets inside the block (a maker note's, the thumbnail's) stay valid; the old GPS IFD's
  entries that the new one does not set are carried over verbatim.

Offsets are counted from the TIFF header (the byte after ``Exif\\0\\0``), as in every EXIF block. Data is placed
on even offsets (TIFF 6.0 word alignment).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from fractions import Fraction

BYTE, ASCII, SHORT, LONG, RATIONAL, UNDEFINED, SRATIONAL = 1, 2, 3, 4, 5, 7, 10  # TIFF 6.0 type codes
EXIF_HEADER = b"Exif\x00\x00"
GPS_IFD = 0x8825  # IFD0 tag pointing at the GPS IFD
BIG_ENDIAN, LITTLE_ENDIAN = ">", "<"


@dataclass(frozen=True)
class Entry:
    """One IFD entry to write: ``tag``, TIFF ``type`` and ``value``: bytes (BYTE, UNDEFINED), str (ASCII, written
    with its NUL), a tuple of ints (SHORT, LONG) or of fractions (RATIONAL, SRATIONAL), or a tuple of entries (a
    sub-IFD: written as a LONG offset to it)."""

    tag: int
    type: int
    value: bytes | str | tuple


@dataclass(frozen=True)
class KeptEntry:
    """An entry read from an existing block, written back verbatim: its 4-byte value field holds the value itself
    or the offset of its data, which stays where it was."""

    tag: int
    type: int
    count: int
    field: bytes


def sub_ifd(tag: int, entries) -> Entry:
    """A pointer entry (Exif, GPS, Interop IFD) to a sub-IFD of ``entries``."""
    return Entry(tag, LONG, tuple(entries))


def entry_data(entry: Entry, order: str) -> tuple[int, bytes]:
    """(count, value bytes) of a plain entry."""
    value = entry.value
    if entry.type in (BYTE, UNDEFINED):
        return len(value), bytes(value)
    if entry.type == ASCII:
        data = value.encode("ascii") + b"\x00"
        return len(data), data
    if entry.type in (SHORT, LONG):
        return len(value), struct.pack(f"{order}{len(value)}{'H' if entry.type == SHORT else 'I'}", *value)
    if entry.type in (RATIONAL, SRATIONAL):
        pairs = [(Fraction(v).numerator, Fraction(v).denominator) for v in value]
        return len(pairs), struct.pack(f"{order}{2 * len(pairs)}{'I' if entry.type == RATIONAL else 'i'}",
                                       *(n for pair in pairs for n in pair))
    raise ValueError(f"tag 0x{entry.tag:04x}: cannot write TIFF type {entry.type}")


def even(offset: int) -> int:
    return offset + (offset & 1)


def ifd_bytes(entries, offset: int, order: str, next_ifd: int = 0) -> bytes:
    """An IFD of ``entries`` (sorted by tag) placed at ``offset``, followed by its out-of-line data and sub-IFDs."""
    entries = sorted(entries, key=lambda e: e.tag)
    fields, extra = [], bytearray()
    data_start = offset + 2 + 12 * len(entries) + 4
    for entry in entries:
        if isinstance(entry, KeptEntry):
            fields.append(struct.pack(f"{order}HHI", entry.tag, entry.type, entry.count) + entry.field)
            continue
        extra += b"\x00" * (len(extra) & 1)
        here = data_start + len(extra)
        if entry.value and isinstance(entry.value, tuple) and isinstance(entry.value[0], Entry):
            extra += ifd_bytes(entry.value, here, order)
            count, data = 1, struct.pack(f"{order}I", here)
        else:
            count, data = entry_data(entry, order)
            if len(data) > 4:
                extra += data
                data = struct.pack(f"{order}I", here)
        fields.append(struct.pack(f"{order}HHI", entry.tag, entry.type, count) + data.ljust(4, b"\x00"))
    return (struct.pack(f"{order}H", len(entries)) + b"".join(fields) + struct.pack(f"{order}I", next_ifd)
            + bytes(extra))


def tiff_bytes(ifd0, order: str = BIG_ENDIAN) -> bytes:
    """A TIFF block (header + IFD0 at offset 8 + everything it points to) of the entries ``ifd0``."""
    header = (b"MM\x00\x2a" if order == BIG_ENDIAN else b"II\x2a\x00") + struct.pack(f"{order}I", 8)
    return header + ifd_bytes(ifd0, 8, order)


def byte_order(tiff: bytes) -> str:
    """``>`` (``MM``) or ``<`` (``II``); ValueError if ``tiff`` does not start with a TIFF header."""
    if tiff[:4] == b"MM\x00\x2a":
        return BIG_ENDIAN
    if tiff[:4] == b"II\x2a\x00":
        return LITTLE_ENDIAN
    raise ValueError("EXIF: no TIFF header (II*/MM*)")


def read_ifd(tiff: bytes, offset: int) -> tuple[list[KeptEntry], int]:
    """The entries of the IFD at ``offset`` and its next-IFD offset; ValueError if it runs past the block."""
    order = byte_order(tiff)
    if offset < 8 or offset + 2 > len(tiff):
        raise ValueError(f"EXIF: IFD offset {offset} outside the {len(tiff)}-byte block")
    (count,) = struct.unpack_from(f"{order}H", tiff, offset)
    end = offset + 2 + 12 * count
    if end + 4 > len(tiff):
        raise ValueError(f"EXIF: the IFD at {offset} ({count} entries) runs past the {len(tiff)}-byte block")
    entries = [KeptEntry(*struct.unpack_from(f"{order}HHI", tiff, at), tiff[at + 8:at + 12])
               for at in range(offset + 2, end, 12)]
    return entries, struct.unpack_from(f"{order}I", tiff, end)[0]


def entry_offset(tiff: bytes, entry: KeptEntry) -> int:
    """The 4-byte field of ``entry`` as an offset (a sub-IFD pointer, or where out-of-line data lies)."""
    return struct.unpack(f"{byte_order(tiff)}I", entry.field)[0]


def with_gps_ifd(tiff: bytes, gps_entries) -> bytes:
    """``tiff`` with a GPS IFD of ``gps_entries`` plus the old GPS IFD's other entries (verbatim), appended at the
    end; IFD0's GPS pointer is rewritten in place, or, if IFD0 has none, IFD0 is rewritten after the new GPS IFD
    with one (its old bytes stay, unused). Nothing else moves."""
    order = byte_order(tiff)
    ifd0_offset = struct.unpack_from(f"{order}I", tiff, 4)[0]
    ifd0, next_ifd = read_ifd(tiff, ifd0_offset)
    pointer = next((i for i, e in enumerate(ifd0) if e.tag == GPS_IFD), None)
    kept = read_ifd(tiff, entry_offset(tiff, ifd0[pointer]))[0] if pointer is not None else []
    new_tags = {e.tag for e in gps_entries}
    out = bytearray(tiff) + b"\x00" * (len(tiff) & 1)
    gps_offset = len(out)
    out += ifd_bytes([*gps_entries, *(e for e in kept if e.tag not in new_tags)], gps_offset, order)
    if pointer is not None:
        struct.pack_into(f"{order}I", out, ifd0_offset + 2 + 12 * pointer + 8, gps_offset)
    else:
        out += b"\x00" * (len(out) & 1)
        struct.pack_into(f"{order}I", out, 4, len(out))
        out += ifd_bytes([*ifd0, Entry(GPS_IFD, LONG, (gps_offset,))], len(out), order, next_ifd)
    return bytes(out)
