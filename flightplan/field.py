"""Read and validate a field to cover: one polygon in WGS84 degrees from a KML or a GeoJSON file.

KML is parsed with defusedxml (no entity expansion, no external references); the first ``Polygon``'s
``outerBoundaryIs`` ring is the field. GeoJSON is parsed with :mod:`json` (RFC 7946): a ``Polygon``, a ``Feature``
holding one, or a ``FeatureCollection`` whose first polygon feature is taken; its exterior ring is the field.
Inner rings (holes) are ignored: the plan covers them too. Coordinates are ``lon,lat[,height]`` in both formats.

The field's local plane is the ENU frame (:class:`flightplan.geodesy.LocalFrame`) at the centroid of its
vertices; its area is the geodesic polygon area on the WGS84 ellipsoid (GeographicLib).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from defusedxml import ElementTree as SafeET

from cliutil.errors import BadInput
from cliutil.paths import path_problem
from flightplan.geodesy import WGS84, LocalFrame, validate_latlon
from cliutil.jsonfile import loads_json

#: Most vertices a field may have (the self-intersection test is quadratic in them).
MAX_VERTICES = 5000
#: Largest file read as a field (a hand-drawn field is a few KB).
MAX_FIELD_FILE_BYTES = 16 * 1024 ** 2
#: Widest field (bounding box diagonal, metres) kept in one local ENU plane and flown from one take-off area.
MAX_EXTENT_M = 10_000.0
#: Narrowest field (metres): a polygon enclosing less than a strip this wide along half its boundary
#: (``perimeter * MIN_WIDTH_M / 2``) is a sliver or a line (collinear points), not a field to cover.
MIN_WIDTH_M = 1.0


@dataclass(frozen=True)
class Field:
    """A simple polygon: vertices in WGS84 degrees (not closed) and the same in the field's ENU plane (metres)."""

    source: str
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    frame: LocalFrame
    enu_m: np.ndarray  # (N, 2) east, north
    area_m2: float  # geodesic area on the WGS84 ellipsoid
    perimeter_m: float


def read_field(path: str | Path) -> Field:
    """Read ``path`` (``.kml`` or ``.geojson``/``.json``) and validate it (:class:`BadInput` naming the file)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".kml", ".geojson", ".json"):
        raise BadInput(f"--area {path}: expected a .kml or .geojson file holding one polygon, got {suffix or 'no suffix'!r}")
    if problem := path_problem(path, folder=False):
        raise BadInput(f"--area {path}: {problem}; expected a .kml or .geojson file holding one polygon")
    with path.open("rb") as stream:
        raw = stream.read(MAX_FIELD_FILE_BYTES + 1)
    if len(raw) > MAX_FIELD_FILE_BYTES:
        raise BadInput(f"--area {path}: larger than {MAX_FIELD_FILE_BYTES // 1024 ** 2} MiB; expected one field polygon")
    lonlat = _kml_ring(raw, path) if suffix == ".kml" else _geojson_ring(raw, path)
    return field_from_lonlat(lonlat, str(path))


def _kml_ring(raw: bytes, path: Path) -> np.ndarray:
    try:
        root = SafeET.fromstring(raw)
    except Exception as error:  # ParseError and defusedxml's refusals (entities, DTDs)
        raise BadInput(f"--area {path}: not a KML document ({error})") from None
    for element in root.iter():
        if _local(element.tag) == "Polygon":
            for outer in element.iter():
                if _local(outer.tag) == "outerBoundaryIs":
                    for coordinates in outer.iter():
                        if _local(coordinates.tag) == "coordinates":
                            return _parse_kml_coordinates(coordinates.text or "", path)
            raise BadInput(f"--area {path}: the KML Polygon has no outerBoundaryIs/LinearRing/coordinates")
    raise BadInput(f"--area {path}: the KML holds no Polygon; expected a field drawn as a polygon")


def _local(tag) -> str:
    """An element's name without its XML namespace."""
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def _parse_kml_coordinates(text: str, path: Path) -> np.ndarray:
    points = []
    for token in text.split():
        try:
            values = [float(v) for v in token.split(",")]
        except ValueError:
            raise BadInput(f"--area {path}: KML coordinate {token[:40]!r} is not lon,lat[,height] numbers") from None
        if len(values) not in (2, 3):
            raise BadInput(f"--area {path}: KML coordinate {token[:40]!r} is not lon,lat[,height]")
        points.append(values[:2])
    return _as_lonlat(points, path)


def _geojson_ring(raw: bytes, path: Path) -> np.ndarray:
    try:
        document = loads_json(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise BadInput(f"--area {path}: not GeoJSON ({error})") from None
    geometry = _first_polygon(document)
    if geometry is None:
        raise BadInput(f"--area {path}: the GeoJSON holds no Polygon; expected a Polygon geometry or feature")
    rings = geometry.get("coordinates")
    if not isinstance(rings, list) or not rings or not isinstance(rings[0], list):
        raise BadInput(f"--area {path}: the Polygon's coordinates are not a list of rings")
    try:
        points = [list(map(float, p))[:2] if len(p) in (2, 3) else [] for p in rings[0]]
    except (TypeError, ValueError):
        raise BadInput(f"--area {path}: the Polygon's exterior ring is not a list of [lon, lat] numbers") from None
    return _as_lonlat(points, path)


def _first_polygon(document) -> dict | None:
    """The first Polygon geometry in a GeoJSON geometry, Feature or FeatureCollection."""
    if not isinstance(document, dict):
        return None
    kind = document.get("type")
    if kind == "Polygon":
        return document
    if kind == "Feature":
        return _first_polygon(document.get("geometry"))
    if kind == "FeatureCollection" and isinstance(document.get("features"), list):
        return next(filter(None, map(_first_polygon, document["features"])), None)
    return None


def _as_lonlat(points: list, path: Path) -> np.ndarray:
    if any(len(p) != 2 for p in points):
        raise BadInput(f"--area {path}: the polygon's points must be lon,lat[,height]")
    lonlat = np.array(points, dtype=np.float64).reshape(-1, 2)
    for lon, lat in lonlat:
        try:
            validate_latlon(lat, lon)
        except ValueError as error:
            raise BadInput(f"--area {path}: {error}") from None
    return lonlat


def field_from_lonlat(lonlat: np.ndarray, source: str) -> Field:
    """Validate a ring of ``(lon, lat)`` degrees (closed or not) and build the :class:`Field`."""
    lonlat = np.asarray(lonlat, dtype=np.float64)
    keep = np.ones(len(lonlat), dtype=bool)
    keep[1:] = np.any(lonlat[1:] != lonlat[:-1], axis=1)  # repeated vertices
    lonlat = lonlat[keep]
    if len(lonlat) > 1 and np.array_equal(lonlat[0], lonlat[-1]):
        lonlat = lonlat[:-1]  # the closing vertex
    if len(lonlat) < 3:
        raise BadInput(f"--area {source}: a polygon needs at least 3 distinct vertices, got {len(lonlat)}")
    if len(lonlat) > MAX_VERTICES:
        raise BadInput(f"--area {source}: {len(lonlat)} vertices; a field may have at most {MAX_VERTICES}")
    first = LocalFrame(lonlat[0, 1], lonlat[0, 0])
    east, north, _ = first.to_enu(lonlat[:, 1], lonlat[:, 0], np.zeros(len(lonlat)))
    extent = float(np.hypot(np.ptp(east), np.ptp(north)))
    if extent > MAX_EXTENT_M:
        raise BadInput(f"--area {source}: the field spans {extent / 1000:.1f} km across; a plan covers at most "
                       f"{MAX_EXTENT_M / 1000:g} km (one take-off area, one local plane): split it")
    centre_lat, centre_lon, _ = first.to_geodetic(east.mean(), north.mean(), 0.0)
    frame = LocalFrame(float(centre_lat), float(centre_lon))
    enu = np.stack(frame.to_enu(lonlat[:, 1], lonlat[:, 0], np.zeros(len(lonlat)))[:2], axis=-1)
    crossing = first_self_intersection(enu)
    if crossing is not None:
        raise BadInput(f"--area {source}: the polygon intersects itself (edges {crossing[0] + 1} and "
                       f"{crossing[1] + 1}); expected a simple polygon")
    area, perimeter = geodesic_area_perimeter(lonlat)
    least = perimeter * MIN_WIDTH_M / 2.0
    if area < least:
        raise BadInput(f"--area {source}: the polygon encloses {area:.3g} m² within its {perimeter:.0f} m boundary, a "
                       f"sliver or a line; expected a field at least {MIN_WIDTH_M:g} m wide ({least:.0f} m² or more)")
    return Field(source, lonlat[:, 1].copy(), lonlat[:, 0].copy(), frame, enu, area, perimeter)


def geodesic_area_perimeter(lonlat: np.ndarray) -> tuple[float, float]:
    """Area (m², unsigned) and perimeter (m) of the closed ring on the WGS84 ellipsoid (GeographicLib)."""
    polygon = WGS84.Polygon()
    for lon, lat in lonlat:
        polygon.AddPoint(lat, lon)
    _, perimeter, area = polygon.Compute(False, True)
    return abs(area), perimeter


def first_self_intersection(ring: np.ndarray) -> tuple[int, int] | None:
    """The first pair of non-adjacent edges of the closed ring ``(N, 2)`` that touch or cross, else ``None``."""
    a, b = ring, np.roll(ring, -1, axis=0)
    count = len(ring)
    for i in range(count - 2):
        j = np.arange(i + 2, count if i > 0 else count - 1)  # edge 0 and edge N-1 share a vertex
        if j.size == 0:
            continue
        hits = _segments_touch(a[i], b[i], a[j], b[j])
        if hits.any():
            return i, int(j[np.argmax(hits)])
    return None


def _cross(o, p, q):
    """z of (p - o) x (q - o), broadcast over rows."""
    return (p[..., 0] - o[..., 0]) * (q[..., 1] - o[..., 1]) - (p[..., 1] - o[..., 1]) * (q[..., 0] - o[..., 0])


def _segments_touch(p1, p2, q1, q2) -> np.ndarray:
    """Whether segment ``p1p2`` meets each segment ``q1[k]q2[k]`` (crossing, touching or overlapping)."""
    d1, d2 = _cross(q1, q2, p1), _cross(q1, q2, p2)
    d3, d4 = _cross(p1, p2, q1), _cross(p1, p2, q2)
    proper = (d1 * d2 < 0) & (d3 * d4 < 0)

    def on_segment(o, p, q, d):  # q collinear with op and inside its box
        return (d == 0) & (np.minimum(o[..., 0], p[..., 0]) <= q[..., 0]) & (q[..., 0] <= np.maximum(o[..., 0], p[..., 0])) \
            & (np.minimum(o[..., 1], p[..., 1]) <= q[..., 1]) & (q[..., 1] <= np.maximum(o[..., 1], p[..., 1]))

    p1b, p2b = np.broadcast_to(p1, q1.shape), np.broadcast_to(p2, q1.shape)
    return proper | on_segment(q1, q2, p1b, d1) | on_segment(q1, q2, p2b, d2) | on_segment(p1b, p2b, q1, d3) \
        | on_segment(p1b, p2b, q2, d4)
