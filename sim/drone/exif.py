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

from PIL import ExifTags, Image, TiffImagePlugin

from capture.geotag import Geotag
from capture.geotag_io import set_exif_gps
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
    "Thumbnail Compression": "Pillow's EXIF writer writes no IFD1 thumbnail (no photogrammetry tool reads it)",
    "Thumbnail XResolution": "no IFD1 thumbnail (above)",
    "Thumbnail YResolution": "no IFD1 thumbnail (above)",
    "Thumbnail ResolutionUnit": "no IFD1 thumbnail (above)",
    "Thumbnail JPEGInterchangeFormat": "no IFD1 thumbnail (above)",
    "Thumbnail JPEGInterchangeFormatLength": "no IFD1 thumbnail (above)",
    "JPEGThumbnail": "no IFD1 thumbnail (above)",
}

# Fixed values of the virtual camera (EXIF 2.3 codes): centred chroma, 72 dpi, sRGB, program auto-exposure with
# a centre-weighted meter (sim.drone.exposure), sunlight, no flash, normal processing, auto white balance.
IFD0_FIXED = {
    ExifTags.Base.Orientation: 1, ExifTags.Base.XResolution: 72.0, ExifTags.Base.YResolution: 72.0,
    ExifTags.Base.ResolutionUnit: 2, ExifTags.Base.YCbCrPositioning: 1,
}
EXIF_FIXED = {
    ExifTags.Base.ExifVersion: b"0230", ExifTags.Base.FlashPixVersion: b"0100",
    ExifTags.Base.ComponentsConfiguration: b"\x01\x02\x03\x00", ExifTags.Base.ColorSpace: 1,
    ExifTags.Base.ExposureProgram: 2, ExifTags.Base.MeteringMode: 2, ExifTags.Base.LightSource: 1,
    ExifTags.Base.Flash: 0x20, ExifTags.Base.ExposureBiasValue: TiffImagePlugin.IFDRational(0, 1),
    ExifTags.Base.SubjectDistance: TiffImagePlugin.IFDRational(0, 1), ExifTags.Base.SubjectDistanceRange: 0,
    ExifTags.Base.FileSource: b"\x00", ExifTags.Base.CustomRendered: 0, ExifTags.Base.ExposureMode: 0,
    ExifTags.Base.WhiteBalance: 0, ExifTags.Base.DigitalZoomRatio: TiffImagePlugin.IFDRational(0, 1),
    ExifTags.Base.SceneCaptureType: 0, ExifTags.Base.GainControl: 0, ExifTags.Base.Contrast: 0,
    ExifTags.Base.Saturation: 0, ExifTags.Base.Sharpness: 0,
}
INTEROP_FIXED = {ExifTags.Interop.InteropIndex: "R98", ExifTags.Interop.InteropVersion: b"0100"}


def dji_exif(tag: Geotag, camera_time: dt.datetime, profile: CameraProfile, size_px: tuple[int, int]) -> Image.Exif:
    """EXIF of a DJI photo of ``size_px`` (width, height) taken at ``camera_time`` (camera clock, written without a
    time zone as DJI does; milliseconds in the three SubSecTime tags) at the geotag's position; ``GPSAltitude`` is
    ``tag.absolute_height_m`` (the caller's height above sea level)."""
    exif = Image.Exif()
    exif.update(IFD0_FIXED)
    stamp, millis = camera_time.strftime("%Y:%m:%d %H:%M:%S"), f"{camera_time.microsecond // 1000:03d}"
    exif.update({ExifTags.Base.Make: MAKE, ExifTags.Base.Model: MODEL, ExifTags.Base.Software: SOFTWARE,
                 ExifTags.Base.DateTime: stamp})
    sub = exif.get_ifd(ExifTags.IFD.Exif)
    sub.update(EXIF_FIXED)
    sub.update({ExifTags.Base.DateTimeOriginal: stamp, ExifTags.Base.DateTimeDigitized: stamp,
                ExifTags.Base.SubsecTime: millis, ExifTags.Base.SubsecTimeOriginal: millis,
                ExifTags.Base.SubsecTimeDigitized: millis,
                ExifTags.Base.ExifImageWidth: int(size_px[0]), ExifTags.Base.ExifImageHeight: int(size_px[1]),
                ExifTags.Base.FocalLength: TiffImagePlugin.IFDRational(round(profile.focal_length_mm * 100), 100),
                ExifTags.Base.FocalLengthIn35mmFilm: round(
                    FULL_FRAME_DIAGONAL_MM / 2.0 / math.tan(math.radians(profile.diagonal_fov_deg) / 2.0))})
    sub[ExifTags.IFD.Interop] = dict(INTEROP_FIXED)
    exif[ExifTags.IFD.Exif] = sub
    set_exif_gps(exif, tag)
    return exif
