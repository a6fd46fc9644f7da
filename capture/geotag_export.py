"""Geotags (``geotags.csv`` + sidecar) exported for the tools people already use (docs/ingest-logs-geotags.md):

* **GPX 1.1** (:func:`geotags_gpx_text`; a flight log's track: :func:`write_track_gpx`): one track, one
  segment, a ``trkpt`` per photo in time order with ``lat``/``lon``, ``ele``, ``time`` (UTC with microseconds)
  and ``name`` (the image). What ``exiftool -geotag``, QGIS, Google Earth and GPS tools read. ``ele`` is the
  geotag's ``absolute_height_m`` (the datum is the sidecar's ``origin_height_datum``, stated in the GPX
  ``metadata/desc``); left out where that height is empty or its datum ``unknown`` (a Litchi log: no absolute
  height at all).
* **ODM ``geo.txt``** (:func:`odm_geo_text`): ``EPSG:4326``, then ``image_name lon lat z``; ``z`` is the geotag's
  ``absolute_height_m`` (left out where GPX leaves ``ele`` out: ODM's z is optional).
* **COLMAP** reference (:func:`colmap_reference_text`): ``image_name X Y Z``, the ENU position in metres in the
  geotags' own frame (the sidecar's origin), for ``model_aligner --ref_is_gps 0 --alignment_type custom``.

Heights are copied, never converted: each export's height is the geotag's documented one.
"""

from __future__ import annotations

import math
from pathlib import Path
from xml.etree import ElementTree

from cliutil.atomic import write_text_atomic

from .geotag import HEIGHT_UNKNOWN
from .geotag_io import PosePrior, load_geotags, read_sidecar
from .track import Track, format_number, format_utc

GPX_NS = "http://www.topografix.com/GPX/1/1"
GPX_SCHEMA_LOCATION = f"{GPX_NS} http://www.topografix.com/GPX/1/1/gpx.xsd"
ODM_CRS = "EPSG:4326"


def read_export_points(csv_path) -> tuple[list[PosePrior], str]:
    """The geotags of ``geotags.csv`` (+ sidecar) in time order, and the datum of their absolute heights (the
    sidecar's ``origin_height_datum``). ValueError naming the file and image when one has no latitude/longitude."""
    priors = sorted(load_geotags(csv_path), key=lambda p: p.utc_time_s)
    for p in priors:
        if not (math.isfinite(p.lat_deg) and math.isfinite(p.lon_deg)):
            raise ValueError(f"{csv_path}: {p.image_name} has no lat_deg/lon_deg to export")
    return priors, read_sidecar(csv_path)[1]


def known_height(point: PosePrior, datum: str) -> bool:
    """Whether the geotag's absolute height is a height to export (given, and its datum known)."""
    return datum != HEIGHT_UNKNOWN and math.isfinite(point.absolute_height_m)


def gpx_text(times_s, lat_deg, lon_deg, ele_m, names, description: str) -> str:
    """A GPX 1.1 document: one ``trk`` with one ``trkseg``, a ``trkpt`` per row with ``ele`` (left out where NaN),
    ``time`` (UTC with microseconds) and, if ``names`` is given, ``name``; ``description`` goes to
    ``metadata/desc``."""
    gpx = ElementTree.Element("gpx", {"xmlns": GPX_NS, "version": "1.1", "creator": "aerostereo",
                                      "xmlns:xsi": "http://www.w3.org/2001/XMLSchema-instance",
                                      "xsi:schemaLocation": GPX_SCHEMA_LOCATION})
    ElementTree.SubElement(ElementTree.SubElement(gpx, "metadata"), "desc").text = description
    segment = ElementTree.SubElement(ElementTree.SubElement(gpx, "trk"), "trkseg")
    for row, (time_s, lat, lon, ele) in enumerate(zip(times_s, lat_deg, lon_deg, ele_m)):
        point = ElementTree.SubElement(segment, "trkpt", {"lat": format_number(lat), "lon": format_number(lon)})
        if math.isfinite(ele):
            ElementTree.SubElement(point, "ele").text = format_number(ele)
        ElementTree.SubElement(point, "time").text = format_utc(time_s)
        if names is not None:
            ElementTree.SubElement(point, "name").text = names[row]
    ElementTree.indent(gpx, space=" ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ElementTree.tostring(gpx, encoding="unicode") + "\n"


def geotags_gpx_text(points: list[PosePrior], datum: str) -> str:
    """The geotags as GPX (module docstring): a point per photo, named by its image."""
    return gpx_text([p.utc_time_s for p in points], [p.lat_deg for p in points], [p.lon_deg for p in points],
                    [p.absolute_height_m if known_height(p, datum) else math.nan for p in points],
                    [p.image_name for p in points],
                    f"photo positions from geotags.csv; ele = absolute_height_m (metres, datum: {datum})")


def write_track_gpx(track: Track, path) -> None:
    """A flight log's track as GPX (atomically): its rows with a position, ``ele`` its ``absolute_height_m`` (above
    sea level as the log gives it; left out where the log has none). ValueError for a track not on UTC."""
    if track.clock != "utc":
        raise ValueError(f"{track.report.source}: GPX times are UTC, but this track's clock is {track.clock!r} "
                         "(give the log's UTC start with --start-time)")
    rows = track.positions_mask()
    write_text_atomic(path, gpx_text(track.time_s[rows], track["lat_deg"][rows], track["lon_deg"][rows],
                                     track["absolute_height_m"][rows], None,
                                     f"{track.report.source}; ele = absolute_height_m (metres above sea level, as "
                                     "the log gives it; absent where the log has none)"))


def odm_geo_text(points: list[PosePrior], datum: str) -> str:
    """ODM's image geolocation file: the CRS line, then ``image_name lon lat [z]`` per photo."""
    lines = [ODM_CRS]
    for p in points:
        z = [format_number(p.absolute_height_m)] if known_height(p, datum) else []
        lines.append(" ".join([p.image_name, format_number(p.lon_deg), format_number(p.lat_deg), *z]))
    return "\n".join(lines) + "\n"


def colmap_reference_text(points: list[PosePrior]) -> str:
    """COLMAP ``model_aligner --ref_images_path`` file: ``image_name X Y Z`` in ENU metres."""
    return "".join(f"{p.image_name} {' '.join(f'{v:.4f}' for v in p.position_enu_m)}\n" for p in points)


def check_line_names(names) -> None:
    """ValueError if an image name would break a whitespace-separated line (geo.txt, COLMAP)."""
    for name in names:
        if not name or any(c.isspace() for c in name):
            raise ValueError(f"image name {name!r} holds whitespace: geo.txt and COLMAP reference lines "
                             "are split on whitespace; rename the photo")


def write_exports(csv_path, gpx: Path | None = None, odm_geo: Path | None = None,
                  colmap_ref: Path | None = None) -> list[str]:
    """Write the requested exports of ``geotags.csv`` (each atomically); returns notes for the user."""
    if not (gpx or odm_geo or colmap_ref):
        return []
    points, datum = read_export_points(csv_path)
    notes = []
    unknown = sum(not known_height(p, datum) for p in points)
    if unknown and (gpx or odm_geo):
        notes.append(f"{unknown} of {len(points)} geotags have no absolute height of known datum (origin_height_datum "
                     f"{datum}): their GPX ele and geo.txt z are left out")
    if odm_geo or colmap_ref:
        check_line_names(p.image_name for p in points)
    for path, text in ((gpx, lambda: geotags_gpx_text(points, datum)), (odm_geo, lambda: odm_geo_text(points, datum)),
                       (colmap_ref, lambda: colmap_reference_text(points))):
        if path:
            write_text_atomic(path, text())
    return notes
