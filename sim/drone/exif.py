"""The EXIF a DJI camera writes, for the virtual drone's photos (:func:`dji_exif`).

The tag set is the one real DJI photos carry (FC300S, FC6360 in ``/work/shared/data``; the test derives it from
them), with values the virtual camera can stand behind, plus the sub-second times ``SubSecTime`` /
``SubSecTimeOriginal`` / ``SubSecTimeDigitized`` (milliseconds; ODM reads ``SubSecTime``). Tags a DJI camera
writes that the virtual camera cannot honestly have are left out; :data:`NOT_WRITTEN` names each with the reason.

Heights: EXIF ``GPSAltitude`` is a height above sea level (``GPSAltitudeRef`` 0 above, 1 below), as DJI writes
it. The virtual world knows ellipsoidal heights only, so the caller gives the geoid undulation N it states for
the scene and the photo carries ``h_ellipsoid - N`` (see ``docs/virtual-drone.md``, "Heights").
"""

from __future__ import annotations

import datetime as dt
import math
from fractions import Fraction

from PIL.ExifTags import IFD, Base, Interop

from capture.exif_tiff import (ASCII, EXIF_HEADER, LONG, RATIONAL, SHORT, SRATIONAL, UNDEFINED, Entry, sub_ifd,
                               tiff_bytes)
from capture.geotag import Geotag
from capture.geotag_io import gps_entries
from flightplan.aircraft import FULL_FRAME_DIAGONAL_MM, CameraProfile
from cliutil.program import package_version

MAKE, MODEL = "DJI", "FC7103"
SOFTWARE = f"aerostereo {package_version()} virtual camera"

#: DJI tags (exifread names) the virtual camera does not write, and why.
NOT_WRITTEN = {
    "Image ImageDescription": "DJI writes the file's path on the SD card (DCIM\\100MEDIA\\...); there is no card",
    "Image XPComment": "DJI firmware text without a published meaning",
    "Image XPKeywords": "DJI firmware text without a published meaning",
    "EXIF ExposureTime": "exposure is a linear gain per channel (sim.drone.exposure), not a shutter time and ISO",
    "EXIF ShutterSpeedValue": "exposure is a gain, not a shutter time",
    "EXIF ISOSpeedRatings": "exposure is a gain, not a sensor sensitivity",
    "EXIF ExposureIndex": "exposure is a gain, not a sensor sensitivity",
    "EXIF FNumber": "the render is a pinhole: no aperture (and no depth of field) is modelled",
    "EXIF ApertureValue": "the render is a pinhole: no aperture is modelled",
    "EXIF MaxApertureValue": "the render is a pinhole: no aperture is modelled",
    "EXIF CompressedBitsPerPixel": "needs the compressed size, which is known only after the EXIF is written",
    "EXIF SceneType": "1 means 'directly photographed'; the image is rendered",
    "EXIF BodySerialNumber": "there is no camera body",
    "Thumbnail Compression": "the virtual camera writes no IFD1 thumbnail (no photogrammetry tool reads it)",
    "Thumbnail XResolution": "no IFD1 thumbnail (above)",
    "Thumbnail YResolution": "no IFD1 thumbnail (above)",
    "Thumbnail ResolutionUnit": "no IFD1 thumbnail (above)",
    "Thumbnail JPEGInterchangeFormat": "no IFD1 thumbnail (above)",
    "Thumbnail JPEGInterchangeFormatLength": "no IFD1 thumbnail (above)",
    "JPEGThumbnail": "no IFD1 thumbnail (above)",
}

# Fixed values of the virtual camera (EXIF 2.3 codes, each with the TIFF type real DJI photos give its tag):
# centred chroma, 72 dpi, sRGB, program auto-exposure with a centre-weighted meter (sim.drone.exposure),
# sunlight, no flash, normal processing, auto white balance, FileSource 3 (digital still camera, as DJI writes).
IFD0_FIXED = (
    Entry(Base.Orientation, SHORT, (1,)), Entry(Base.XResolution, RATIONAL, (72,)),
    Entry(Base.YResolution, RATIONAL, (72,)), Entry(Base.ResolutionUnit, SHORT, (2,)),
    Entry(Base.YCbCrPositioning, SHORT, (1,)),
)
EXIF_FIXED = (
    Entry(Base.ExifVersion, UNDEFINED, b"0230"), Entry(Base.FlashPixVersion, UNDEFINED, b"0100"),
    Entry(Base.ComponentsConfiguration, UNDEFINED, b"\x01\x02\x03\x00"), Entry(Base.ColorSpace, SHORT, (1,)),
    Entry(Base.ExposureProgram, SHORT, (2,)), Entry(Base.MeteringMode, SHORT, (2,)),
    Entry(Base.LightSource, SHORT, (1,)), Entry(Base.Flash, SHORT, (0x20,)),
    Entry(Base.ExposureBiasValue, SRATIONAL, (0,)), Entry(Base.SubjectDistance, RATIONAL, (0,)),
    Entry(Base.SubjectDistanceRange, SHORT, (0,)), Entry(Base.FileSource, UNDEFINED, b"\x03"),
    Entry(Base.CustomRendered, SHORT, (0,)), Entry(Base.ExposureMode, SHORT, (0,)),
    Entry(Base.WhiteBalance, SHORT, (0,)), Entry(Base.DigitalZoomRatio, RATIONAL, (0,)),
    Entry(Base.SceneCaptureType, SHORT, (0,)), Entry(Base.GainControl, SHORT, (0,)),
    Entry(Base.Contrast, SHORT, (0,)), Entry(Base.Saturation, SHORT, (0,)), Entry(Base.Sharpness, SHORT, (0,)),
)
INTEROP_FIXED = (Entry(Interop.InteropIndex, ASCII, "R98"), Entry(Interop.InteropVersion, UNDEFINED, b"0100"))


def dji_exif(tag: Geotag, camera_time: dt.datetime, profile: CameraProfile, size_px: tuple[int, int]) -> bytes:
    """The EXIF block (APP1 payload: ``Exif\\0\\0`` + TIFF) of a DJI photo of ``size_px`` (width, height) taken
    at ``camera_time`` (camera clock, written without a time zone as DJI does; milliseconds in the three
    SubSecTime tags) at the geotag's position; ``GPSAltitude`` is ``tag.absolute_height_m`` (the caller's height
    above sea level). Every tag has the TIFF type a real DJI photo gives it."""
    stamp, millis = camera_time.strftime("%Y:%m:%d %H:%M:%S"), f"{camera_time.microsecond // 1000:03d}"
    focal_35mm = round(FULL_FRAME_DIAGONAL_MM / 2.0 / math.tan(math.radians(profile.diagonal_fov_deg) / 2.0))
    exif_ifd = (*EXIF_FIXED, Entry(Base.DateTimeOriginal, ASCII, stamp), Entry(Base.DateTimeDigitized, ASCII, stamp),
                *(Entry(code, ASCII, millis) for code in (Base.SubsecTime, Base.SubsecTimeOriginal,
                                                          Base.SubsecTimeDigitized)),
                Entry(Base.ExifImageWidth, LONG, (int(size_px[0]),)),
                Entry(Base.ExifImageHeight, LONG, (int(size_px[1]),)),
                Entry(Base.FocalLength, RATIONAL, (Fraction(round(profile.focal_length_mm * 100), 100),)),
                Entry(Base.FocalLengthIn35mmFilm, SHORT, (focal_35mm,)), sub_ifd(IFD.Interop, INTEROP_FIXED))
    ifd0 = (*IFD0_FIXED, Entry(Base.Make, ASCII, MAKE), Entry(Base.Model, ASCII, MODEL),
            Entry(Base.Software, ASCII, SOFTWARE), Entry(Base.DateTime, ASCII, stamp),
            sub_ifd(IFD.Exif, exif_ifd), sub_ifd(IFD.GPSInfo, gps_entries(tag)))
    return EXIF_HEADER + tiff_bytes(ifd0)
