"""Photo metadata: EXIF times and GPS, DJI XMP ``drone-dji:`` attitude and heights -> ``PhotoInfo``/``Track``.

Pillow reads the EXIF IFDs and the raw XMP packet; the packet is parsed with defusedxml (DTDs and entities
refused), accepting both attribute (``drone-dji:GimbalYawDegree="+45.00"``) and element forms, and both
``GpsLongitude`` and DJI's ``GpsLongtitude``. EXIF ``DateTimeOriginal`` is the camera clock, whole seconds
unless ``SubSecTimeOriginal`` refines it; ``OffsetTimeOriginal`` (if any) converts it to UTC, otherwise the
clock is read as UTC and geotagging estimates the offset.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
from defusedxml import ElementTree as SafeET
from PIL import ExifTags, Image, UnidentifiedImageError

from ..attitude import wrap_deg
from ..track import LogFormatError, ReadReport, Track, position_problem

DRONE_DJI_NS = "http://www.dji.com/drone-dji/1.0/"
PHOTO_SUFFIXES = (".jpg", ".jpeg")
XMP_FIELDS = {
    "GpsLatitude": "lat_deg", "GpsLongitude": "lon_deg", "GpsLongtitude": "lon_deg",
    "AbsoluteAltitude": "absolute_height_m", "RelativeAltitude": "height_above_takeoff_m",
    "GimbalYawDegree": "gimbal_yaw_deg", "GimbalPitchDegree": "gimbal_pitch_deg", "GimbalRollDegree": "gimbal_roll_deg",
    "FlightYawDegree": "aircraft_yaw_deg", "FlightPitchDegree": "aircraft_pitch_deg", "FlightRollDegree": "aircraft_roll_deg",
}


@dataclass
class PhotoInfo:
    """What one photo says about itself. ``exif_time_s``: camera clock, seconds since the epoch (NaN if none)."""

    path: Path
    exif_time_s: float = math.nan
    time_resolution_s: float = 1.0
    values: dict[str, float] = field(default_factory=dict)  # track field -> value (EXIF GPS, then XMP)
    problems: list[str] = field(default_factory=list)

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
    try:
        with Image.open(info.path) as image:
            exif = image.getexif()
            xmp = image.info.get("xmp")
    except (UnidentifiedImageError, OSError) as error:
        raise LogFormatError(f"{info.path}: not a readable image ({error})") from None
    read_exif_time(exif, info)
    read_exif_gps(exif, info)
    if xmp:
        try:
            info.values.update(parse_dji_xmp(xmp))
        except ValueError as error:
            info.problems.append(f"XMP: {error}")
    drop_unusable_position(info)
    return info


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
    offset = str(sub.get(ExifTags.Base.OffsetTimeOriginal, "")).strip("\x00 ")
    if len(offset) == 6 and offset[0] in "+-" and offset[3] == ":":
        sign = 1 if offset[0] == "+" else -1
        stamp -= sign * timedelta(hours=int(offset[1:3]), minutes=int(offset[4:6]))
    info.exif_time_s = stamp.timestamp()


def read_exif_gps(exif: Image.Exif, info: PhotoInfo) -> None:
    """GPS IFD latitude/longitude (DMS rationals + N/S/E/W) and altitude -> ``info.values``."""
    gps = exif.get_ifd(ExifTags.IFD.GPSInfo)
    try:
        lat = dms_to_deg(gps.get(ExifTags.GPS.GPSLatitude), gps.get(ExifTags.GPS.GPSLatitudeRef), "NS")
        lon = dms_to_deg(gps.get(ExifTags.GPS.GPSLongitude), gps.get(ExifTags.GPS.GPSLongitudeRef), "EW")
    except (TypeError, ValueError, ZeroDivisionError) as error:
        info.problems.append(f"EXIF GPS: {error}")
        return
    if lat is not None and lon is not None:
        info.values.update(lat_deg=lat, lon_deg=lon)
    altitude = gps.get(ExifTags.GPS.GPSAltitude)
    if altitude is not None:
        below = gps.get(ExifTags.GPS.GPSAltitudeRef) in (1, b"\x01")
        info.values["absolute_height_m"] = -float(altitude) if below else float(altitude)


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


def parse_dji_xmp(packet: bytes | str) -> dict[str, float]:
    """``drone-dji:`` values of an XMP packet (attribute and element forms) -> track fields.

    Raises ValueError on malformed XML, on DTDs/entities (refused, never expanded) and on non-numeric values.
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
                raw[key[len(prefix):]] = value
        if isinstance(element.tag, str) and element.tag.startswith(prefix) and element.text:
            raw[element.tag[len(prefix):]] = element.text
    values = {}
    for tag, name in XMP_FIELDS.items():
        if tag in raw:
            try:
                value = float(raw[tag].strip())
            except ValueError:
                raise ValueError(f"drone-dji:{tag} = {raw[tag][:40]!r} is not a number") from None
            values[name] = float(wrap_deg(value)) if name.endswith("yaw_deg") else value
    return values


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
