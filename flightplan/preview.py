"""Previews of a mission a person can look at: KML (Google Earth), GeoJSON and a PNG plot.

KML and GeoJSON carry WGS84 degrees; their third coordinate is the height **above take-off** in metres
(KML ``relativeToGround``, exact where the ground is level with the take-off point). Lines that cross the
antimeridian are cut there (RFC 7946 section 3.1.9), so viewers do not draw them around the globe.
The PNG (matplotlib's Agg canvas, no display needed) shows the plan in the local ENU plane of the POI (metres),
with the modelled flown path.
All writers are atomic.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from flightplan import flown_path, litchi
from cliutil.atomic import atomic_path, write_text_atomic
from flightplan.geodesy import LocalFrame

KML_NAMESPACE = "http://www.opengis.net/kml/2.2"


def split_at_antimeridian(lon_deg: np.ndarray, lat_deg: np.ndarray, height_m: np.ndarray) -> list[np.ndarray]:
    """Cut a line into pieces that never jump across +-180 deg; each piece is ``(K, 3)`` lon, lat, height.

    At a crossing both pieces get an interpolated end point on the antimeridian (+180 on one side, -180 on the
    other).
    """
    points = np.stack([lon_deg, lat_deg, height_m], axis=-1).astype(np.float64)
    pieces, current = [], [points[0]]
    for previous, point in zip(points[:-1], points[1:]):
        step = point[0] - previous[0]
        if abs(step) > 180.0:
            edge = 180.0 if previous[0] > 0 else -180.0
            unwrapped_step = step - np.sign(step) * 360.0
            t = (edge - previous[0]) / unwrapped_step
            crossing = previous + t * np.array([unwrapped_step, *(point[1:] - previous[1:])])
            current.append(np.array([edge, *crossing[1:]]))
            pieces.append(np.array(current))
            current = [np.array([-edge, *crossing[1:]])]
        current.append(point)
    pieces.append(np.array(current))
    return pieces


def _mission_line(mission: litchi.Mission) -> list[np.ndarray]:
    return split_at_antimeridian(
        mission.column("longitude_deg"), mission.column("latitude_deg"), mission.column("altitude_m")
    )


def coordinates_text(points: np.ndarray) -> str:
    """KML ``coordinates`` text: ``lon,lat[,height]`` tuples separated by spaces, shortest exact numbers."""
    return " ".join(",".join(litchi.format_number(v) for v in point) for point in points)


def _kml_placemark(parent: ET.Element, name: str, description: str = "") -> ET.Element:
    placemark = ET.SubElement(parent, "Placemark")
    ET.SubElement(placemark, "name").text = name
    if description:
        ET.SubElement(placemark, "description").text = description
    return placemark


def _kml_point(placemark: ET.Element, lon: float, lat: float, height_m: float) -> None:
    point = ET.SubElement(placemark, "Point")
    ET.SubElement(point, "altitudeMode").text = "relativeToGround"
    ET.SubElement(point, "coordinates").text = coordinates_text(np.array([[lon, lat, height_m]]))


def _waypoint_description(index: int, waypoint: litchi.Waypoint) -> str:
    return (
        f"row {index}: {waypoint.altitude_m:.2f} m above take-off, heading {waypoint.heading_deg:.2f} deg, "
        f"gimbal pitch {waypoint.gimbal_pitch_deg:.2f} deg, speed {waypoint.speed_m_s:.3f} m/s"
    )


def mission_to_kml(mission: litchi.Mission, name: str = "aerostereo mission") -> str:
    """KML document with the path (extruded to the ground), one placemark per waypoint and the POI."""
    kml = ET.Element("kml", xmlns=KML_NAMESPACE)
    document = ET.SubElement(kml, "Document")
    ET.SubElement(document, "name").text = name
    style = ET.SubElement(document, "Style", id="path")
    line_style = ET.SubElement(style, "LineStyle")
    ET.SubElement(line_style, "color").text = "ff00aaff"
    ET.SubElement(line_style, "width").text = "3"
    path = _kml_placemark(document, "Flight path (waypoint to waypoint)")
    ET.SubElement(path, "styleUrl").text = "#path"
    geometry = ET.SubElement(path, "MultiGeometry")
    for piece in _mission_line(mission):
        line = ET.SubElement(geometry, "LineString")
        ET.SubElement(line, "extrude").text = "1"
        ET.SubElement(line, "altitudeMode").text = "relativeToGround"
        ET.SubElement(line, "coordinates").text = coordinates_text(piece)
    folder = ET.SubElement(document, "Folder")
    ET.SubElement(folder, "name").text = "Waypoints"
    for index, waypoint in enumerate(mission.waypoints, start=1):
        placemark = _kml_placemark(folder, f"WP{index}", _waypoint_description(index, waypoint))
        _kml_point(placemark, waypoint.longitude_deg, waypoint.latitude_deg, waypoint.altitude_m)
    first = mission.waypoints[0]
    if first.has_poi:
        poi = _kml_placemark(document, "POI", f"{first.poi_altitude_m:.2f} m above take-off")
        _kml_point(poi, first.poi_longitude_deg, first.poi_latitude_deg, first.poi_altitude_m)
    ET.indent(kml)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(kml, encoding="unicode") + "\n"


def mission_to_geojson(mission: litchi.Mission) -> dict:
    """GeoJSON FeatureCollection: the path (MultiLineString), the waypoints and the POI (Points)."""
    path = {
        "type": "Feature",
        "geometry": {"type": "MultiLineString", "coordinates": [piece.tolist() for piece in _mission_line(mission)]},
        "properties": {"name": "flight path", "height": "metres above take-off"},
    }
    waypoints = [
        {
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [w.longitude_deg, w.latitude_deg, w.altitude_m]},
            "properties": {
                "name": f"WP{index}",
                "height_above_takeoff_m": w.altitude_m,
                "heading_deg": w.heading_deg,
                "gimbal_pitch_deg": w.gimbal_pitch_deg,
                "speed_m_s": w.speed_m_s,
            },
        }
        for index, w in enumerate(mission.waypoints, start=1)
    ]
    first = mission.waypoints[0]
    poi = []
    if first.has_poi:
        poi = [
            {
                "type": "Feature",
                "geometry": {
                    "type": "Point",
                    "coordinates": [first.poi_longitude_deg, first.poi_latitude_deg, first.poi_altitude_m],
                },
                "properties": {"name": "POI", "height_above_takeoff_m": first.poi_altitude_m},
            }
        ]
    return {"type": "FeatureCollection", "features": [path, *waypoints, *poi]}


def write_kml(mission: litchi.Mission, path: str | Path, name: str = "aerostereo mission") -> Path:
    """Write :func:`mission_to_kml` to ``path`` atomically."""
    return write_text_atomic(path, mission_to_kml(mission, name))


def write_geojson(mission: litchi.Mission, path: str | Path) -> Path:
    """Write :func:`mission_to_geojson` to ``path`` atomically."""
    return write_text_atomic(path, json.dumps(mission_to_geojson(mission), indent=1) + "\n")


def write_plot_png(
    mission: litchi.Mission, center_lat_deg: float, center_lon_deg: float, path: str | Path, title: str = ""
) -> Path:
    """Top view in the POI's ENU plane: waypoints, the modelled flown path, the start and the POI."""
    frame = LocalFrame(center_lat_deg, center_lon_deg, 0.0)
    lat, lon = mission.column("latitude_deg"), mission.column("longitude_deg")
    east, north, _ = frame.to_enu(lat, lon, np.zeros_like(lat))
    vertices = np.stack([east, north], axis=-1)
    flown = flown_path.curved_turns_path(vertices, mission.column("curve_size_m"))
    figure = Figure(figsize=(7, 7), dpi=100, layout="constrained")  # Agg canvas, no pyplot state
    axes = figure.subplots()
    axes.plot(flown[:, 0], flown[:, 1], "-", color="tab:orange", lw=1.5, label="modelled flown path")
    axes.plot(east, north, "o", color="tab:blue", ms=3, label="waypoints")
    axes.plot(east[0], north[0], "s", color="tab:green", ms=8, label="start (WP1)")
    if len(east) > 1:
        axes.annotate("", xy=vertices[1], xytext=vertices[0], arrowprops={"arrowstyle": "->", "color": "tab:green"})
    axes.plot(0.0, 0.0, "*", color="tab:red", ms=12, label="POI / centre")
    axes.set_aspect("equal")
    axes.set_xlabel("east (m)")
    axes.set_ylabel("north (m)")
    axes.set_title(title or f"orbit around {center_lat_deg:.6f}, {center_lon_deg:.6f}", fontsize=9)
    axes.grid(True, lw=0.3)
    axes.legend(loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=4, fontsize=8)
    with atomic_path(path) as temporary:
        figure.savefig(temporary, format="png")
    return Path(path)
