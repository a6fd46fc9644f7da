"""Photo metadata: EXIF times and GPS, DJI XMP ``drone-dji:`` attitude and heights -> ``PhotoInfo``/``Track``;
DJI factory calibration and RTK status -> :class:`CameraXmp`.

Pillow reads the EXIF IFDs and the raw XMP packet; the packet is parsed with defusedxml (DTDs and entities
refused), accepting both attribute (``drone-dji:GimbalYawDegree="+45.00"``) and element forms, and both
``GpsLongitude`` and DJI's ``GpsLongtitude``. EXIF ``DateTimeOriginal`` is the camera clock, whole seconds
unless ``SubSecTimeOriginal`` refines it; ``OffsetTimeOriginal`` (if any) converts it to UTC, otherwise the
clock is read as UTC and geotagging estimates the offset.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
from defusedxml import ElementTree as SafeET
from PIL import ExifTags, Image, UnidentifiedImageError

from cliutil.program import one_line

from ..attitude import wrap_deg
from ..track import LogFormatError, ReadReport, Track, name_list, position_problem

DRONE_DJI_NS = "http://www.dji.com/drone-dji/1.0/"
PHOTO_SUFFIXES = (".jpg", ".jpeg")
XMP_FIELDS = {
    "GpsLatitude": "lat_deg", "GpsLongitude": "lon_deg", "GpsLongtitude": "lon_deg",
    "AbsoluteAltitude": "absolute_height_m", "RelativeAltitude": "height_above_takeoff_m",
    "GimbalYawDegree": "gimbal_yaw_deg", "GimbalPitchDegree": "gimbal_pitch_deg", "GimbalRollDegree": "gimbal_roll_deg",
    "FlightYawDegree": "aircraft_yaw_deg", "FlightPitchDegree": "aircraft_pitch_deg", "FlightRollDegree": "aircraft_roll_deg",
}
#: Physical range of every number a photo may give (track field -> [low, high]); a value outside it, or not finite
#: (XMP ``inf``, ``nan``, ``1e308``), is unusable: that field is treated as missing and the photo's problem noted.
#: Heights in metres: from below the lowest land (Dead Sea shore, -430 m) to well above any drone's service
#: ceiling (DJI: 6000 m) and Mount Everest; angles in degrees, one turn either way (DJI writes +-180).
MAX_HEIGHT_M = 12_000.0
MIN_HEIGHT_M = -1_000.0
FIELD_RANGES: dict[str, tuple[float, float]] = {
    "lat_deg": (-90.0, 90.0), "lon_deg": (-180.0, 360.0),
    "absolute_height_m": (MIN_HEIGHT_M, MAX_HEIGHT_M), "height_above_takeoff_m": (MIN_HEIGHT_M, MAX_HEIGHT_M),
    **{f"{part}_{axis}_deg": (-360.0, 360.0) for part in ("gimbal", "aircraft") for axis in ("yaw", "pitch", "roll")},
}


@dataclass
class PhotoInfo:
    """What one photo says about itself. ``exif_time_s``: camera clock, seconds since the epoch (NaN if none): UTC
    where ``exif_time_is_utc`` (the photo wrote its zone, ``OffsetTimeOriginal``), else the clock's own local time
    read as if it were UTC."""

    path: Path
    exif_time_s: float = math.nan
    time_resolution_s: float = 1.0
    values: dict[str, float] = field(default_factory=dict)  # track field -> value (EXIF GPS, then XMP)
    problems: list[str] = field(default_factory=list)
    exif_time_is_utc: bool = False

    @property
    def name(self) -> str:
        return self.path.name


def list_photos(folder) -> list[Path]:
    """JPEG files in ``folder`` (not recursive), sorted by name."""
    folder = Path(folder)
    if not folder.is_dir():
        raise LogFormatError(f"{folder}: not a folder of photos")
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in PHOTO_SUFFIXES and p.is_file())


def read_photo(path) -> PhotoInfo:
    """EXIF + XMP of one JPEG. Unreadable parts are listed in ``problems``; a non-image raises LogFormatError."""
    info = PhotoInfo(Path(path))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            with Image.open(info.path) as image:
                exif = image.getexif()
                xmp = image.info.get("xmp")
        except (UnidentifiedImageError, OSError) as error:
            raise LogFormatError(f"{info.path}: not a readable image ({error})") from None
        read_exif_time(exif, info)
        read_exif_gps(exif, info)
    note_damaged_exif(caught, info)
    if xmp:
        try:
            values, problems = dji_xmp_values(dji_xmp_text(xmp))
        except ValueError as error:
            info.problems.append(f"XMP: {error}")
        else:
            info.values.update(values)
            info.problems += [f"XMP: {problem}, ignored" for problem in problems]
    drop_unusable_position(info)
    return info


def note_damaged_exif(caught: list[warnings.WarningMessage], info: PhotoInfo) -> None:
    """Pillow's EXIF parser (``TiffImagePlugin``) warns of a damaged EXIF ("Corrupt EXIF data", "Truncated File
    Read") and reads on without the rest: each such warning becomes a problem of ``info`` (a counted note of the
    photos report, not a line of Python's on stderr); any other warning is issued again as it was."""
    for caught_warning in caught:
        if Path(caught_warning.filename).name == "TiffImagePlugin.py":
            info.problems.append(f"EXIF: damaged ({one_line(str(caught_warning.message))}), the fields it held "
                                 "treated as missing")
        else:
            warnings.warn_explicit(caught_warning.message, caught_warning.category, caught_warning.filename,
                                   caught_warning.lineno)


def value_problem(name: str, value: float) -> str | None:
    """Why ``value`` of track field ``name`` is unusable (not finite, outside :data:`FIELD_RANGES`), or None."""
    low, high = FIELD_RANGES[name]
    if not low <= value <= high:  # also refuses NaN
        return f"is not a finite number within [{low:g}, {high:g}]"
    return None


def drop_unusable_position(info: PhotoInfo) -> None:
    """Remove a latitude/longitude (EXIF GPS, or XMP over it) outside WGS84 ranges, noting why in ``problems``."""
    if "lat_deg" in info.values and "lon_deg" in info.values:
        if problem := position_problem(info.values["lat_deg"], info.values["lon_deg"]):
            info.problems.append(f"GPS: {problem}, ignored")
            del info.values["lat_deg"], info.values["lon_deg"]


def read_exif_time(exif: Image.Exif, info: PhotoInfo) -> None:
    """DateTimeOriginal (+ SubSecTimeOriginal, + OffsetTimeOriginal) -> ``info.exif_time_s``."""
    sub = exif.get_ifd(ExifTags.IFD.Exif)
    text = sub.get(ExifTags.Base.DateTimeOriginal) or exif.get(ExifTags.Base.DateTime)
    if not text:
        info.problems.append("EXIF: no DateTimeOriginal")
        return
    try:
        stamp = datetime.strptime(str(text).strip("\x00 "), "%Y:%m:%d %H:%M:%S").replace(tzinfo=timezone.utc)
    except ValueError:
        info.problems.append(f"EXIF: DateTimeOriginal {text!r} is not 'YYYY:MM:DD HH:MM:SS'")
        return
    subsec = str(sub.get(ExifTags.Base.SubsecTimeOriginal, "")).strip("\x00 ")
    if subsec.isdigit():
        stamp += timedelta(seconds=int(subsec) / 10 ** len(subsec))
        info.time_resolution_s = 10.0 ** -len(subsec)
    elif subsec:
        info.problems.append(f"EXIF: SubSecTimeOriginal {subsec[:40]!r} is not digits, ignored (whole seconds)")
    offset = str(sub.get(ExifTags.Base.OffsetTimeOriginal, "")).strip("\x00 ")
    if offset:
        if not (len(offset) == 6 and offset[0] in "+-" and offset[3] == ":" and offset[1:3].isdigit()
                and offset[4:6].isdigit()):
            info.problems.append(f"EXIF: OffsetTimeOriginal {offset[:40]!r} is not '+HH:MM', ignored")
        else:
            sign = 1 if offset[0] == "+" else -1
            try:
                stamp -= sign * timedelta(hours=int(offset[1:3]), minutes=int(offset[4:6]))
            except OverflowError:
                info.problems.append(f"EXIF: DateTimeOriginal {text!r} - {offset} is out of the calendar's range")
                return
            info.exif_time_is_utc = True
    info.exif_time_s = stamp.timestamp()


def read_exif_gps(exif: Image.Exif, info: PhotoInfo) -> None:
    """GPS IFD latitude/longitude (DMS rationals + N/S/E/W) and altitude -> ``info.values``; a field that cannot
    be read, or an altitude outside :data:`FIELD_RANGES`, is left out and noted in ``info.problems``."""
    gps = exif.get_ifd(ExifTags.IFD.GPSInfo)
    try:
        lat = dms_to_deg(gps.get(ExifTags.GPS.GPSLatitude), gps.get(ExifTags.GPS.GPSLatitudeRef), "NS")
        lon = dms_to_deg(gps.get(ExifTags.GPS.GPSLongitude), gps.get(ExifTags.GPS.GPSLongitudeRef), "EW")
    except (TypeError, ValueError, ZeroDivisionError) as error:
        info.problems.append(f"EXIF GPS: latitude/longitude {error}, ignored")
        lat = lon = None
    if lat is not None and lon is not None:
        info.values.update(lat_deg=lat, lon_deg=lon)  # checked as a pair by drop_unusable_position
    altitude = gps.get(ExifTags.GPS.GPSAltitude)
    if altitude is None:
        return
    below = gps.get(ExifTags.GPS.GPSAltitudeRef) in (1, b"\x01")
    try:
        height = -float(altitude) if below else float(altitude)
    except (TypeError, ValueError, ZeroDivisionError):
        info.problems.append(f"EXIF GPS: GPSAltitude {str(altitude)[:40]!r} is not a number, ignored")
        return
    if problem := value_problem("absolute_height_m", height):
        info.problems.append(f"EXIF GPS: GPSAltitude {height!r} m {problem}, ignored")
    else:
        info.values["absolute_height_m"] = height


def dms_to_deg(dms, ref, letters: str) -> float | None:
    """EXIF (deg, min, sec) + reference letter -> signed degrees; None if absent."""
    if dms is None:
        return None
    degrees, minutes, seconds = (float(part) for part in dms)
    value = degrees + minutes / 60.0 + seconds / 3600.0
    ref = (ref or letters[0]).strip("\x00 ").upper()
    if ref not in letters:
        raise ValueError(f"reference {ref!r} is not one of {letters}")
    return -value if ref == letters[1] else value


def dji_xmp_text(packet: bytes | str) -> dict[str, str]:
    """Every ``drone-dji:`` value of an XMP packet as text, by tag name (attribute and element forms).

    Raises ValueError on malformed XML and on DTDs/entities (refused, never expanded).
    """
    if isinstance(packet, bytes):
        packet = packet.decode("utf-8", errors="replace")
    start = packet.find("<x:xmpmeta")
    end = packet.rfind("</x:xmpmeta>")
    body = packet[start:end + len("</x:xmpmeta>")] if 0 <= start < end else packet
    try:
        root = SafeET.fromstring(body, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except Exception as error:  # defusedxml raises ParseError or its own DefusedXmlException subclasses
        raise ValueError(f"unreadable XMP packet ({type(error).__name__}: {error})") from None
    raw: dict[str, str] = {}
    prefix = "{" + DRONE_DJI_NS + "}"
    for element in root.iter():
        for key, value in element.attrib.items():
            if key.startswith(prefix):
                raw[key[len(prefix):]] = value.strip()
        if isinstance(element.tag, str) and element.tag.startswith(prefix) and element.text:
            raw[element.tag[len(prefix):]] = element.text.strip()
    return raw


def xmp_number(raw: dict[str, str], tag: str) -> float:
    """``drone-dji:<tag>`` of :func:`dji_xmp_text`'s result as a float; ValueError naming the tag if not a number."""
    try:
        return float(raw[tag])
    except ValueError:
        raise ValueError(f"drone-dji:{tag} = {raw[tag][:40]!r} is not a number") from None


def dji_xmp_values(raw: dict[str, str]) -> tuple[dict[str, float], list[str]]:
    """:func:`dji_xmp_text`'s values -> (track fields, problems): a value that is not a number within
    :data:`FIELD_RANGES` is left out and described (tag, text, expected range); yaws wrapped to [-180, 180)."""
    values, problems = {}, []
    for tag, name in XMP_FIELDS.items():
        if tag not in raw:
            continue
        try:
            value = xmp_number(raw, tag)
        except ValueError as error:
            problems.append(str(error))
            continue
        if problem := value_problem(name, value):
            problems.append(f"drone-dji:{tag} = {raw[tag][:40]!r} {problem}")
        else:
            values[name] = float(wrap_deg(value)) if name.endswith("yaw_deg") else value
    return values, problems


def parse_dji_xmp(packet: bytes | str) -> dict[str, float]:
    """``drone-dji:`` values of an XMP packet (attribute and element forms) -> track fields.

    Raises ValueError on malformed XML, on DTDs/entities (refused, never expanded) and on a value that is not a
    number within :data:`FIELD_RANGES`.
    """
    values, problems = dji_xmp_values(dji_xmp_text(packet))
    if problems:
        raise ValueError(problems[0])
    return values


#: DJI ``RtkFlag`` of a fixed RTK solution (0 none, 16 single point, 32-49 float, 50 fixed).
RTK_FIXED = 50
#: Sanity bounds on factory calibration: focal length (and DewarpData fx, fy) in multiples of the photo's longer
#: side (a 170 deg fisheye to a 1000 mm lens on a 35 mm frame), and the size of any distortion coefficient.
FOCAL_RANGE_SIDES = (0.1, 30.0)
MAX_DISTORTION_COEFFICIENT = 10.0
MAX_RTK_STD_M = 1000.0


@dataclass(frozen=True)
class FactoryCalibration:
    """A DJI camera's factory calibration (XMP), in pixels of the full-resolution ``width`` x ``height`` photo.

    DJI puts the image centre at (W/2, H/2) (``CalibratedOpticalCenterX/Y`` 800/650 on a 1600x1300 photo), as
    COLMAP does; ours is 0.5 px less (pixel (0,0) is the centre of the top-left pixel). ``focal_px``:
    ``CalibratedFocalLength``; ``centre_px``: ``CalibratedOpticalCenterX/Y`` (the image centre when absent);
    ``dewarp``: ``DewarpData``'s fx, fy (px), cx, cy (px offsets from ``centre_px``), k1, k2, p1, p2, k3 (OpenCV
    radial-tangential, on normalised coordinates), or None; ``dewarped``: ``DewarpFlag`` 1, the JPEG is
    already undistorted.
    """

    width: int
    height: int
    focal_px: float
    centre_px: tuple[float, float]
    dewarp: tuple[float, ...] | None
    dewarped: bool


@dataclass(frozen=True)
class RtkStatus:
    """DJI ``RtkFlag`` and ``RtkStdLon/Lat/Hgt`` as east/north/up standard deviations (m, 1 sigma; None if absent)."""

    flag: int
    std_enu_m: tuple[float, float, float] | None

    @property
    def fixed(self) -> bool:
        return self.flag == RTK_FIXED


@dataclass(frozen=True)
class CameraXmp:
    """What a photo's ``drone-dji:`` XMP says about its camera and its position fix (None where absent)."""

    calibration: FactoryCalibration | None
    rtk: RtkStatus | None


def checked(raw: dict[str, str], tag: str, low: float, high: float) -> float:
    """``drone-dji:<tag>`` as a float within [low, high]; ValueError naming the tag and the bounds otherwise."""
    value = xmp_number(raw, tag)
    if not low <= value <= high:  # also refuses NaN
        raise ValueError(f"drone-dji:{tag} = {raw[tag][:40]!r} is not within [{low:g}, {high:g}]")
    return value


def factory_calibration(raw: dict[str, str], width: int, height: int) -> FactoryCalibration | None:
    """:class:`FactoryCalibration` from :func:`dji_xmp_text`'s values, or None without ``CalibratedFocalLength``."""
    if "CalibratedFocalLength" not in raw:
        return None
    focal_range = tuple(bound * max(width, height) for bound in FOCAL_RANGE_SIDES)
    focal = checked(raw, "CalibratedFocalLength", *focal_range)
    centre = tuple(checked(raw, f"CalibratedOpticalCenter{axis}", 0.0, size) if f"CalibratedOpticalCenter{axis}" in raw
                   else size / 2.0 for axis, size in (("X", width), ("Y", height)))
    dewarp = dewarp_data(raw["DewarpData"], focal_range, (width, height)) if "DewarpData" in raw else None
    flag = checked(raw, "DewarpFlag", 0, 1) if "DewarpFlag" in raw else 0
    return FactoryCalibration(width, height, focal, centre, dewarp, flag == 1)


def dewarp_data(text: str, focal_range, size) -> tuple[float, ...]:
    """``DewarpData`` ("date;fx,fy,cx,cy,k1,k2,p1,p2,k3") -> the 9 numbers, each checked against sane bounds."""
    fields = text.rsplit(";", 1)[-1].split(",")
    try:
        values = tuple(float(field) for field in fields)
    except ValueError:
        values = ()
    if len(values) != 9:
        raise ValueError(f"drone-dji:DewarpData = {text[:80]!r} is not 'date;fx,fy,cx,cy,k1,k2,p1,p2,k3'")
    bounds = [focal_range] * 2 + [(-size[0] / 2, size[0] / 2), (-size[1] / 2, size[1] / 2)] \
        + [(-MAX_DISTORTION_COEFFICIENT, MAX_DISTORTION_COEFFICIENT)] * 5
    for name, value, (low, high) in zip("fx fy cx cy k1 k2 p1 p2 k3".split(), values, bounds):
        if not low <= value <= high:
            raise ValueError(f"drone-dji:DewarpData {name} = {value} is not within [{low:g}, {high:g}]")
    return values


def rtk_status(raw: dict[str, str]) -> RtkStatus | None:
    """:class:`RtkStatus` from :func:`dji_xmp_text`'s values, or None when the photo has no ``RtkFlag``."""
    if "RtkFlag" not in raw:
        return None
    flag = checked(raw, "RtkFlag", 0, 255)
    if flag != int(flag):
        raise ValueError(f"drone-dji:RtkFlag = {raw['RtkFlag'][:40]!r} is not an integer")
    tags = ("RtkStdLon", "RtkStdLat", "RtkStdHgt")
    std = tuple(checked(raw, tag, 0.0, MAX_RTK_STD_M) for tag in tags) if all(t in raw for t in tags) else None
    return RtkStatus(int(flag), std)


def read_camera_xmp(path) -> CameraXmp:
    """Factory calibration and RTK status of one photo; :class:`LogFormatError` naming the photo if a value is
    not a finite number within sane bounds (or the file is not an image)."""
    path = Path(path)
    try:
        with Image.open(path) as image:
            width, height = image.size
            xmp = image.info.get("xmp")
    except (UnidentifiedImageError, OSError) as error:
        raise LogFormatError(f"{path}: not a readable image ({error})") from None
    if not xmp:
        return CameraXmp(None, None)
    try:
        raw = dji_xmp_text(xmp)
        return CameraXmp(factory_calibration(raw, width, height), rtk_status(raw))
    except ValueError as error:
        raise LogFormatError(f"{path}: XMP {error}") from None


def read_photos(folder) -> tuple[list[PhotoInfo], ReadReport]:
    """Read every JPEG in ``folder``; unreadable files become rejects (file named), never silent skips."""
    report = ReadReport(str(folder), "photos")
    photos = []
    for path in list_photos(folder):
        report.rows_read += 1
        try:
            photo = read_photo(path)
        except LogFormatError as error:
            report.reject(None, f"unreadable photo: {error}")
            continue
        for problem in photo.problems:
            report.notes.append(f"{path.name}: {problem}")
        photos.append(photo)
    report.rows_used = len(photos)
    flawed = [photo.name for photo in photos if photo.problems]
    if flawed:
        report.notes.append(f"{len(flawed)} of {len(photos)} photos have unusable metadata, those fields treated as "
                            f"missing: {name_list(flawed)}")
    return photos, report


def read_photos_track(folder) -> Track:
    """The photos' own metadata as a track on the camera clock (one row and one photo event per photo)."""
    photos, report = read_photos(folder)
    timed = [p for p in photos if math.isfinite(p.exif_time_s) and {"lat_deg", "lon_deg"} <= set(p.values)]
    for photo in photos:
        if photo not in timed:
            report.reject(None, f"no EXIF time or no GPS position: {photo.path}")
    report.rows_used = len(timed)
    if not timed:
        raise LogFormatError(f"{folder}: no photo with both an EXIF time and a GPS position")
    names = sorted({name for p in timed for name in p.values})
    columns = {name: np.array([p.values.get(name, math.nan) for p in timed]) for name in names}
    times = np.array([p.exif_time_s for p in timed])
    return Track.from_rows(times, columns, report, photo_times_s=times, clock="camera")
