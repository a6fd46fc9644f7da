"""A truncated photo is found by walking its scans to the EOI marker (:func:`capture.jpeg_segments.image_end`):
baseline, progressive (several scans with tables between them) and restart-marked JPEGs, with bytes appended
after EOI as DJI appends its MPF preview."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from capture.jpeg_segments import image_end, replace_metadata, split_jpeg

SAVE_OPTIONS = {"baseline": {}, "progressive": {"progressive": True}, "restart markers": {"restart_marker_blocks": 1}}


def noisy_jpeg(**options) -> bytes:
    """A 64 x 48 JPEG of noise (its entropy-coded data holds stuffed 0xFF00 bytes)."""
    pixels = np.random.default_rng(4).integers(0, 256, (48, 64, 3), dtype=np.uint8)
    out = io.BytesIO()
    Image.fromarray(pixels).save(out, format="JPEG", quality=95, **options)
    return out.getvalue()


def first_scan(data: bytes) -> int:
    segments, image = split_jpeg(data)
    return len(data) - len(image)


@pytest.mark.parametrize("kind", SAVE_OPTIONS)
def test_the_eoi_is_found_past_stuffed_bytes_and_before_an_appended_preview(kind):
    data = noisy_jpeg(**SAVE_OPTIONS[kind])
    assert data.endswith(b"\xff\xd9") and b"\xff\x00" in data[first_scan(data):]
    assert (b"\xff\xd0" in data) == (kind == "restart markers")
    preview = noisy_jpeg()  # as a DJI photo carries its MPF preview after the first image's EOI
    assert image_end(data + preview, first_scan(data)) == len(data)


@pytest.mark.parametrize("kind", SAVE_OPTIONS)
def test_every_cut_after_the_first_scan_starts_is_refused_naming_where_the_file_ends(kind):
    data = noisy_jpeg(**SAVE_OPTIONS[kind])
    start = first_scan(data)
    for end in range(start, len(data), max(1, (len(data) - start) // 40)):
        with pytest.raises(ValueError, match=f"truncated: the file ends at byte {end} before"):
            image_end(data[:end], start)
    with pytest.raises(ValueError, match="truncated"):
        replace_metadata(data[:-1], lambda old: old or b"", lambda old: old or b"")
