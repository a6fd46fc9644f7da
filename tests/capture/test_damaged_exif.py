"""Pillow's warnings while a photo's EXIF is read: its EXIF parser's become counted notes of the photo, any other
warning goes on as it was."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest
from PIL import Image

from capture.logs.photos import PhotoInfo, note_damaged_exif


def caught(message: str, category: type[Warning], filename: str) -> warnings.WarningMessage:
    return warnings.WarningMessage(category(message), category, filename, 982)


def test_the_exif_parsers_warning_is_a_note_of_the_photo():
    info = PhotoInfo(Path("DJI_0005.JPG"))
    tiff_plugin = str(Path(Image.__file__).with_name("TiffImagePlugin.py"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing may be issued
        note_damaged_exif([caught("Corrupt EXIF data.  Expecting to read 4 bytes\nbut only got 2. ", UserWarning,
                                  tiff_plugin)], info)
    assert info.problems == ["EXIF: damaged (Corrupt EXIF data. Expecting to read 4 bytes but only got 2.), the "
                             "fields it held treated as missing"]


def test_another_warning_is_issued_again():
    info = PhotoInfo(Path("DJI_0005.JPG"))
    bomb = caught("Image size (200000000 pixels) exceeds limit", Image.DecompressionBombWarning,
                  str(Path(Image.__file__)))
    with pytest.warns(Image.DecompressionBombWarning, match="exceeds limit"):
        note_damaged_exif([bomb], info)
    assert info.problems == []
