"""Geotag files: ``geotags.csv`` + ``geotags.json`` (docs/interfaces.md), pose priors for recon, EXIF/XMP write-back.

``load_geotags(path)`` is what recon (pose priors) and the simulator's replay read: one ``PosePrior`` per photo
with the ENU camera position, ``R_world_cam`` (ENU <- OpenCV camera) and the ENU origin.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
from PIL.ExifTags import GPS
from scipy.spatial.transform import Rotation

from flightplan.geodesy import LocalFrame
from cliutil.jsonfile import loads_json

from cliutil.atomic import write_bytes_atomic, write_text_atomic
from .exif_tiff import ASCII, BYTE, EXIF_HEADER, GPS_IFD, RATIONAL, Entry, sub_ifd, tiff_bytes, with_gps_ifd
from .geotag import HEIGHT_UNKNOWN, PHOTO_ACCURACY, PHOTO_SOURCE, Geotag, GeotagResult
from .jpeg_segments import replace_metadata
from .logs.photos import DRONE_DJI_NS, FIELD_RANGES
from .track import csv_errors, csv_rows, format_number, format_utc, parse_utc
from .xmp_update import with_dji_fields

XMP_META_NS = "adobe:ns:meta/"
RDF_NS = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
XPACKET_BEGIN = '<?xpacket begin="\ufeff" id="W5M0MpCehiHzreSzNTczkc9d"?>\n'
XPACKET_END = '<?xpacket end="w"?>'

GEOTAG_COLUMNS = (
    "image_name,utc_time,lat_deg,lon_deg,height_above_takeoff_m,absolute_height_m,aircraft_yaw_deg,"
    "aircraft_pitch_deg,aircraft_roll_deg,gimbal_yaw_deg,gimbal_pitch_deg,gimbal_roll_deg,source,time_offset_s,"
    "east_m,north_m,up_m,qw,qx,qy,qz"
).split(",")

#: Farthest a geotag's ENU position may lie from the origin on each axis (m): DJI's longest links reach 20 km, and
#: 100 km out the tangent plane is already 785 m off the ellipsoid (d^2 / 2R): beyond, ENU is no local frame.
MAX_ENU_M = 100_000.0
#: Range of each number a geotags.csv row may hold (column -> [low, high]): a photo's (capture/logs/photos.py),
#: longitudes as the geotagger writes them and GPX reads them ([-180, 180]), ENU within :data:`MAX_ENU_M`,
#: quaternion components within a unit quaternion's.
GEOTAG_RANGES: dict[str, tuple[float, float]] = {
    **{name: FIELD_RANGES[name] for name in GEOTAG_COLUMNS if name in FIELD_RANGES}, "lon_deg": (-180.0, 180.0),
    **{name: (-MAX_ENU_M, MAX_ENU_M) for name in ("east_m", "north_m", "up_m")},
    **{name: (-1.0, 1.0) for name in ("qw", "qx", "qy", "qz")},
}


@dataclass(frozen=True)
class PosePrior:
    """A photo's pose prior: ENU position (m), R_world_cam (3x3, or None if no attitude), origin, UTC time, and
    the geotag's WGS84 degrees and ``absolute_height_m`` (datum: the sidecar's ``origin_height_datum``; NaN if
    the row has none)."""

    image_name: str
    position_enu_m: np.ndarray
    R_world_cam: np.ndarray | None
    origin: LocalFrame
    utc_time_s: float
    lat_deg: float = math.nan
    lon_deg: float = math.nan
    absolute_height_m: float = math.nan


def sidecar_path(csv_path) -> Path:
    """``geotags.csv`` -> ``geotags.json`` beside it."""
    return Path(csv_path).with_suffix(".json")


def geotag_paths(csv_path) -> tuple[Path, Path]:
    """``(csv_path, its sidecar)``; ValueError when they are the same file (``--out geotags.json``)."""
    csv_path = Path(csv_path)
    if sidecar_path(csv_path) == csv_path:
        raise ValueError(f"{csv_path}: the geotags CSV would overwrite its own .json sidecar; name it e.g. "
                         f"{csv_path.with_suffix('.csv').name}")
    return csv_path, sidecar_path(csv_path)


def tag_row(tag: Geotag, offset_s: float) -> list[str]:
    """One CSV row (strings) for a geotag, in GEOTAG_COLUMNS order."""
    quaternion = [math.nan] * 4
    if tag.R_world_cam is not None:
        x, y, z, w = Rotation.from_matrix(tag.R_world_cam).as_quat()
        quaternion = [w, x, y, z] if w >= 0 else [-w, -x, -y, -z]
    numbers = [tag.lat_deg, tag.lon_deg, tag.height_above_takeoff_m, tag.absolute_height_m,
               *tag.aircraft_ypr_deg, *tag.gimbal_ypr_deg]
    return ([tag.image_name, format_utc(tag.time_s)] + [format_number(v) for v in numbers]
            + [tag.source, format_number(offset_s)] + [format_number(v) for v in (*tag.enu_m, *quaternion)])


def write_geotags(result: GeotagResult, csv_path) -> tuple[Path, Path]:
    """Write ``geotags.csv``, then its ``.json`` sidecar, each atomically; returns both paths."""
    csv_path, json_path = geotag_paths(csv_path)
    table = io.StringIO()
    writer = csv.writer(table, lineterminator="\n")
    writer.writerow(GEOTAG_COLUMNS)
    writer.writerows(tag_row(tag, result.clock.offset_s) for tag in result.tags)
    sidecar = {
        "origin": result.origin.to_dict(),
        "origin_height_known": result.origin_height_known,
        "origin_height_datum": result.origin_height_datum,
        "clock_offset_s": result.clock.offset_s,
        "clock_offset_std_s": result.clock.std_s if math.isfinite(result.clock.std_s) else None,
        "clock_offset_method": result.clock.method,
        "sources": [{"file": r.source, "kind": r.kind, "rows_read": r.rows_read, "rows_used": r.rows_used,
                     "rejected": len(r.rejected), "notes": r.notes} for r in result.sources],
        "untagged": [{"image_name": name, "reason": reason} for name, reason in result.untagged],
        "from_photos": {"source": PHOTO_SOURCE, "accuracy": PHOTO_ACCURACY,
                        "images": [{"image_name": name, "reason": reason} for name, reason in result.from_photos]},
        "notes": result.notes,
    }
    write_text_atomic(csv_path, table.getvalue())
    write_text_atomic(json_path, json.dumps(sidecar, indent=2) + "\n")
    return csv_path, json_path


def read_sidecar(csv_path) -> tuple[LocalFrame, str]:
    """The sidecar's ENU origin and ``origin_height_datum`` (``unknown`` if absent); ValueError naming the file."""
    path = sidecar_path(csv_path)
    try:
        sidecar = loads_json(path.read_text(encoding="utf-8"))
        return LocalFrame.from_dict(sidecar["origin"]), str(sidecar.get("origin_height_datum", HEIGHT_UNKNOWN))
    except (OSError, KeyError, ValueError, TypeError, AttributeError) as error:
        raise ValueError(f"{path}: cannot read the origin ({error})") from None


def optional_number(text: str) -> float:
    """A CSV cell as a float; empty = NaN."""
    return float(text) if text != "" else math.nan


def load_geotags(csv_path) -> list[PosePrior]:
    """Read ``geotags.csv`` (+ sidecar origin) into pose priors; raises ValueError naming file:line (and the column
    of a number outside :data:`GEOTAG_RANGES`: no place on Earth, or beyond a local ENU frame)."""
    csv_path = Path(csv_path)
    origin = read_sidecar(csv_path)[0]
    with csv_path.open(encoding="utf-8", newline="") as handle:
        reader = csv.DictReader(handle)
        with csv_errors(csv_path, reader):
            fieldnames = reader.fieldnames
        if fieldnames != GEOTAG_COLUMNS:
            raise ValueError(f"{csv_path}:1: expected the geotags.csv header {','.join(GEOTAG_COLUMNS)}, "
                             f"got {','.join(reader.fieldnames or [])}")
        priors = []
        for line, row in csv_rows(reader, csv_path):
            if problem := range_problem(row):
                raise ValueError(f"{csv_path}:{line}: {problem}")
            try:
                position = np.array([float(row[k]) for k in ("east_m", "north_m", "up_m")])
                q = [row[k] for k in ("qw", "qx", "qy", "qz")]
                rotation = None if "" in q else Rotation.from_quat([float(v) for v in q], scalar_first=True).as_matrix()
                geodetic = [optional_number(row[k]) for k in ("lat_deg", "lon_deg", "absolute_height_m")]
                priors.append(PosePrior(row["image_name"], position, rotation, origin, parse_utc(row["utc_time"]),
                                        *geodetic))
            except (ValueError, TypeError) as error:
                raise ValueError(f"{csv_path}:{line}: east_m,north_m,up_m must be numbers, lat_deg,lon_deg,"
                                 f"absolute_height_m numbers or empty, qw,qx,qy,qz numbers or all empty, utc_time "
                                 f"ISO 8601 ({error})") from None
    return priors


def range_problem(row: dict[str, str]) -> str | None:
    """Why a geotags.csv row's numbers are impossible (a given one not a finite number within
    :data:`GEOTAG_RANGES`: ``column: ...``), or None; text that is no number at all is left to the parser."""
    for name, (low, high) in GEOTAG_RANGES.items():
        text = row.get(name) or ""
        try:
            value = float(text)
        except ValueError:
            continue
        if not low <= value <= high:  # also refuses NaN
            return f"{name} {value:g} is not a finite number within [{low:g}, {high:g}]"
    return None


def dji_xmp_fields(tag: Geotag) -> dict[str, str]:
    """The geotag as ``drone-dji:`` XMP fields (DJI's names and sign style, name -> text): ``GpsLatitude``,
    ``GpsLongitude``, ``AbsoluteAltitude`` the geotag's absolute height, ``RelativeAltitude`` its height above
    take-off, ``Gimbal/Flight Yaw/Pitch/RollDegree``; a value that is unknown (NaN) is left out."""
    values = {"GpsLatitude": tag.lat_deg, "GpsLongitude": tag.lon_deg,
              "AbsoluteAltitude": tag.absolute_height_m, "RelativeAltitude": tag.height_above_takeoff_m}
    for prefix, angles in (("Gimbal", tag.gimbal_ypr_deg), ("Flight", tag.aircraft_ypr_deg)):
        values.update({f"{prefix}YawDegree": angles[0], f"{prefix}PitchDegree": angles[1], f"{prefix}RollDegree": angles[2]})
    return {k: f"{v:+.8f}" for k, v in values.items() if math.isfinite(v)}


def dji_xmp_packet(tag: Geotag, extra: dict[str, str] | None = None) -> bytes:
    """A minimal XMP packet with the geotag's :func:`dji_xmp_fields` as ``drone-dji:`` attributes, plus the
    ``extra`` ``drone-dji:`` attributes given as text (e.g. :func:`dji_calibration_attributes`).

    Built as an element tree (:mod:`xml.etree.ElementTree`) and serialised by it, so every value is escaped
    whatever characters it holds (``&<>"`` and line breaks included); the elements and attributes are named with
    DJI's prefixes (``x:``, ``rdf:``, ``drone-dji:``, declared on them), which prefix-matching readers rely on."""
    texts = dji_xmp_fields(tag) | (extra or {})
    meta = ElementTree.Element("x:xmpmeta", {"xmlns:x": XMP_META_NS})
    rdf = ElementTree.SubElement(meta, "rdf:RDF", {"xmlns:rdf": RDF_NS})
    ElementTree.SubElement(rdf, "rdf:Description", {"rdf:about": "DJI Meta Data", "xmlns:drone-dji": DRONE_DJI_NS}
                           | {f"drone-dji:{name}": text for name, text in texts.items()})
    ElementTree.indent(meta, space=" ")
    return (XPACKET_BEGIN + ElementTree.tostring(meta, encoding="unicode") + "\n" + XPACKET_END).encode("utf-8")


def dji_calibration_attributes(fx: float, fy: float, cx: float, cy: float, width: int, height: int,
                               distortion, date: str) -> dict[str, str]:
    """A camera's calibration as DJI writes it into XMP (``drone-dji:`` attribute name -> text).

    Input: focal lengths and principal point in pixels of a ``width`` x ``height`` image, OUR convention (pixel
    (0, 0) is the centre of the top-left pixel), OpenCV ``distortion`` (k1, k2, p1, p2, k3) on normalised
    coordinates, the calibration ``date`` (text). Output, DJI's convention (pixel corners, so the image centre is
    ``width / 2``): ``CalibratedFocalLength`` fx, ``CalibratedOpticalCenterX/Y`` the image centre,
    ``DewarpData`` ``"date;fx,fy,dcx,dcy,k1,k2,p1,p2,k3"`` with ``dcx, dcy`` the principal point's offset from
    that centre, and ``DewarpFlag`` 0 (the image is not dewarped).
    """
    centre_x, centre_y = width / 2.0, height / 2.0
    numbers = (fx, fy, cx + 0.5 - centre_x, cy + 0.5 - centre_y, *distortion)
    if len(numbers) != 9:
        raise ValueError(f"DewarpData needs 5 distortion coefficients (k1, k2, p1, p2, k3), got {len(numbers) - 4}")
    return {"CalibratedFocalLength": f"{fx:.6f}", "CalibratedOpticalCenterX": f"{centre_x:.6f}",
            "CalibratedOpticalCenterY": f"{centre_y:.6f}",
            "DewarpData": f"{date};" + ",".join(f"{float(v):.12f}" for v in numbers), "DewarpFlag": "0"}


def deg_to_dms(value: float) -> tuple[float, float, float]:
    """|value| in degrees as (degrees, minutes, seconds), the first two whole, seconds rounded to 1e-6."""
    degrees = math.floor(abs(value))
    minutes = math.floor((abs(value) - degrees) * 60.0)
    seconds = (abs(value) - degrees - minutes / 60.0) * 3600.0
    return float(degrees), float(minutes), round(seconds, 6)


def gps_entries(tag: Geotag) -> tuple[Entry, ...]:
    """The geotag as EXIF GPS IFD entries, typed as the EXIF standard (and DJI) writes them: GPSVersionID 2.3,
    latitude/longitude (DMS rationals, seconds to 1e-6) with their N/S, E/W references and, if known, the
    absolute height as GPSAltitudeRef (0 above, 1 below the datum) + GPSAltitude (metres to 0.01 mm)."""
    entries = [Entry(GPS.GPSVersionID, BYTE, b"\x02\x03\x00\x00")]
    for ref, code, value, letters in ((GPS.GPSLatitudeRef, GPS.GPSLatitude, tag.lat_deg, "NS"),
                                      (GPS.GPSLongitudeRef, GPS.GPSLongitude, tag.lon_deg, "EW")):
        degrees, minutes, seconds = deg_to_dms(value)
        entries += [Entry(ref, ASCII, letters[value < 0]),
                    Entry(code, RATIONAL, (int(degrees), int(minutes), Fraction(round(seconds * 10**6), 10**6)))]
    if math.isfinite(tag.absolute_height_m):
        entries += [Entry(GPS.GPSAltitudeRef, BYTE, bytes([tag.absolute_height_m < 0])),
                    Entry(GPS.GPSAltitude, RATIONAL, (Fraction(round(abs(tag.absolute_height_m) * 10**5), 10**5),))]
    return tuple(entries)


def geotagged_jpeg(data: bytes, tag: Geotag) -> bytes:
    """A JPEG file's bytes with the geotag in its EXIF GPS IFD and its DJI XMP fields, the compressed image and
    every other segment, EXIF tag and XMP field untouched (:mod:`capture.jpeg_segments`,
    :func:`capture.exif_tiff.with_gps_ifd`, :mod:`capture.xmp_update`). ValueError for a damaged JPEG/EXIF/XMP."""
    gps = gps_entries(tag)

    def exif(old: bytes | None) -> bytes:
        if old is None:
            return EXIF_HEADER + tiff_bytes([sub_ifd(GPS_IFD, gps)])
        return EXIF_HEADER + with_gps_ifd(old[len(EXIF_HEADER):], gps)

    def xmp(old: bytes | None) -> bytes:
        return dji_xmp_packet(tag) if old is None else with_dji_fields(old, dji_xmp_fields(tag))

    return replace_metadata(data, exif, xmp)


def write_exif_copy(tag: Geotag, source: Path, target: Path) -> None:
    """Copy a JPEG with the geotag written into its metadata (:func:`geotagged_jpeg`), atomically; ValueError
    naming ``source`` if its metadata cannot be edited."""
    try:
        data = geotagged_jpeg(Path(source).read_bytes(), tag)
    except ValueError as error:
        raise ValueError(f"{source}: {error}") from None
    write_bytes_atomic(target, data)


def write_exif_copies(result: GeotagResult, photos_dir, out_dir) -> list[Path]:
    """Geotagged copies of every tagged photo in ``out_dir`` (never modifies the originals)."""
    out_dir = Path(out_dir)
    if out_dir.resolve() == Path(photos_dir).resolve():
        raise ValueError(f"{out_dir}: refusing to overwrite the original photos; choose another folder")
    written = []
    for tag in result.tags:
        target = out_dir / tag.image_name
        write_exif_copy(tag, Path(photos_dir) / tag.image_name, target)
        written.append(target)
    return written
