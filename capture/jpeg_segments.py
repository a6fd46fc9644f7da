"""A JPEG's metadata segments replaced without touching its image data (``geotag --write-exif``).

A JPEG file is ``SOI``, marker segments (APPn metadata, quantisation and Huffman tables, the frame header), then
from the first ``SOS`` on the compressed image data up to ``EOI`` (and whatever a camera appends after it: DJI
puts its MPF preview image there). :func:`replace_metadata` swaps the EXIF APP1 and the XMP APP1 payloads and
copies every other byte verbatim; the decoded pixels cannot change, because the tables, the frame header and the
entropy-coded data are the original bytes.

One segment refers to sizes and positions in the file: the Multi-Picture Format index (APP2 ``MPF``, CIPA
DC-007) gives the first image's length and the later images' offsets. Its numbers are updated by how much the
replaced segments grew (the segment itself keeps its size).
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable

from .exif_tiff import EXIF_HEADER, byte_order, entry_offset, read_ifd

SOI = b"\xff\xd8"
APP0, APP1, APP2, SOS, EOI = 0xE0, 0xE1, 0xE2, 0xDA, 0xD9
STANDALONE = {0x01, *range(0xD0, 0xD8)}  # TEM, RST0-7: markers without a length
XMP_HEADER = b"http://ns.adobe.com/xap/1.0/\x00"
MPF_HEADER = b"MPF\x00"
MP_ENTRY = 0xB002  # MP Index IFD: 16 bytes per image (attribute, size, offset, two dependent-image entries)
MAX_PAYLOAD = 0xFFFF - 2  # a segment's length field counts itself


def split_jpeg(data: bytes) -> tuple[list[bytes], bytes]:
    """The marker segments between ``SOI`` and the first ``SOS`` (each whole: marker, length, payload) and the
    file from that ``SOS`` on. ValueError if ``data`` is not a JPEG or a segment runs past its end."""
    if data[:2] != SOI:
        raise ValueError("not a JPEG (no SOI marker)")
    segments, at = [], 2
    while True:
        if at + 2 > len(data) or data[at] != 0xFF:
            raise ValueError(f"JPEG: no marker at byte {at} (truncated or damaged header)")
        marker = data[at + 1]
        if marker == 0xFF:  # fill byte before a marker
            at += 1
        elif marker == SOS:
            return segments, data[at:]
        elif marker in STANDALONE:
            segments.append(data[at:at + 2])
            at += 2
        elif marker == EOI or at + 4 > len(data):
            raise ValueError(f"JPEG: no image data (end at byte {at} before any scan)")
        else:
            end = at + 2 + int.from_bytes(data[at + 2:at + 4], "big")
            if end > len(data) or end < at + 4:
                raise ValueError(f"JPEG: the segment at byte {at} runs past the end of the file")
            segments.append(data[at:end])
            at = end


#: The next marker in entropy-coded data: an 0xFF that is not a stuffed 0xFF00 or a restart marker RST0-7.
_NEXT_MARKER = re.compile(rb"\xff(?![\x00\xd0-\xd7])")


def image_end(data: bytes, at: int) -> int:
    """The offset just past the ``EOI`` of the image whose first ``SOS`` is at byte ``at``: scans (their
    entropy-coded data holds 0xFF only stuffed or as a restart marker) and the table segments between them are
    walked. ValueError naming the byte where the file ends when it ends before ``EOI`` (a truncated photo)."""
    while at + 2 <= len(data):
        marker = data[at + 1]
        if data[at] != 0xFF:
            raise ValueError(f"JPEG: no marker at byte {at} after the image data (damaged)")
        if marker == EOI:
            return at + 2
        if marker == 0xFF or marker in STANDALONE:  # fill byte; a restart marker between scans
            at += 1 if marker == 0xFF else 2
            continue
        if at + 4 > len(data):
            break
        at += 2 + int.from_bytes(data[at + 2:at + 4], "big")
        if marker == SOS:
            found = _NEXT_MARKER.search(data, at)
            if found is None:
                break
            at = found.start()
    raise ValueError(f"JPEG: truncated: the file ends at byte {len(data)} before the image data's EOI marker")


def payload_of(segment: bytes, marker: int, header: bytes) -> bytes | None:
    """The payload (after the length) of an APPn segment with ``marker`` whose payload starts with ``header``."""
    return segment[4:] if segment[1] == marker and segment[4:4 + len(header)] == header else None


def app_segment(marker: int, payload: bytes) -> bytes:
    """A marker segment of ``payload``; ValueError if it exceeds a segment's 65533 bytes."""
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"JPEG: a {len(payload)}-byte APP{marker - APP0} payload exceeds a segment's "
                         f"{MAX_PAYLOAD} bytes")
    return bytes([0xFF, marker]) + struct.pack(">H", len(payload) + 2) + payload


def replace_metadata(data: bytes, exif: Callable[[bytes | None], bytes],
                     xmp: Callable[[bytes | None], bytes]) -> bytes:
    """``data`` with its first EXIF APP1 payload (``Exif\\0\\0`` + TIFF) replaced by ``exif(old payload or
    None)`` and its first XMP APP1 payload (after the XMP namespace header) by ``xmp(old packet or None)``; a new
    EXIF segment goes after a leading JFIF APP0, a new XMP one after the EXIF. Every other byte is copied.
    ValueError for a file that ends before its image's ``EOI`` (:func:`image_end`)."""
    segments, image = split_jpeg(data)
    image_end(data, len(data) - len(image))  # a truncated photo is refused, not copied
    new = list(segments)
    exif_at = next((i for i, s in enumerate(segments) if payload_of(s, APP1, EXIF_HEADER) is not None), None)
    if exif_at is None:
        exif_at = 1 if segments and segments[0][1] == APP0 else 0
        new.insert(exif_at, app_segment(APP1, exif(None)))
    else:
        new[exif_at] = app_segment(APP1, exif(segments[exif_at][4:]))
    xmp_at = next((i for i, s in enumerate(new) if payload_of(s, APP1, XMP_HEADER) is not None), None)
    if xmp_at is None:
        new.insert(exif_at + 1, app_segment(APP1, XMP_HEADER + xmp(None)))
    else:
        new[xmp_at] = app_segment(APP1, XMP_HEADER + xmp(new[xmp_at][4 + len(XMP_HEADER):]))
    return SOI + b"".join(with_mpf_updated(segments, new)) + image


def with_mpf_updated(old: list[bytes], new: list[bytes]) -> list[bytes]:
    """``new`` (``old`` with some segments replaced or inserted, none removed) with its MPF index updated: the
    first image's size grows by the bytes the header grew, later images' offsets (counted from the MPF
    segment's TIFF header) by the bytes it grew after the MPF segment. ValueError for a damaged MPF index."""
    at = next((i for i, s in enumerate(new) if payload_of(s, APP2, MPF_HEADER) is not None), None)
    if at is None:
        return new
    mpf = new[at]
    old_at = old.index(mpf)
    grown = sum(map(len, new)) - sum(map(len, old))
    grown_after = sum(map(len, new[at + 1:])) - sum(map(len, old[old_at + 1:]))
    return new[:at] + [mpf_shifted(mpf, grown, grown_after)] + new[at + 1:]


def mpf_shifted(segment: bytes, grown: int, grown_after: int) -> bytes:
    """An MPF APP2 segment with the first MP entry's size + ``grown`` and the others' non-zero offsets +
    ``grown_after``."""
    start = 4 + len(MPF_HEADER)
    tiff = segment[start:]
    order = byte_order(tiff)
    entries, _ = read_ifd(tiff, struct.unpack_from(f"{order}I", tiff, 4)[0])
    index = next((e for e in entries if e.tag == MP_ENTRY), None)
    if index is None or entry_offset(tiff, index) + index.count > len(tiff) or index.count % 16:
        raise ValueError("JPEG: damaged MPF index (no MP entry list within the segment)")
    out = bytearray(segment)
    for k in range(index.count // 16):
        size_at = start + entry_offset(tiff, index) + 16 * k + 4
        size, offset = struct.unpack_from(f"{order}II", out, size_at)
        if k == 0:
            size += grown
        elif offset:
            offset += grown_after
        struct.pack_into(f"{order}II", out, size_at, size, offset)
    return bytes(out)
