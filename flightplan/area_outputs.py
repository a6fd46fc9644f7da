"""What ``aerostereo-mission --area`` writes: one Litchi CSV per flight, the overview (KML, GeoJSON, PNG) and the
predictions (a table on stdout, ``area.json``).

KML and GeoJSON carry WGS84 degrees (``lon,lat[,height above take-off m]``): the field polygon, each orbit's
waypoint ring, each well-covered disc (a 72-gon), and per flight the line take-off -> orbit centres -> take-off.
The PNG shows the same in the field's ENU plane (metres). The plan is written whole or not at all
(:func:`write_area_plan`).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from flightplan.aircraft import DJI_MINI_SE
from flightplan.area import AreaPlan
from cliutil.atomic import TEMP_MARK, atomic_path, write_text_atomic
from flightplan.litchi import write_mission_csv
from flightplan.preview import KML_NAMESPACE, coordinates_text

OVERVIEW_NAMES = ("area.kml", "area.geojson", "area.png", "area.json")
SUMMARY_NAME = OVERVIEW_NAMES[-1]  # written last: a folder with the plan's other files but not this one is a half plan
#: The hidden folder inside ``--out`` that a plan is written into before it is moved in (:func:`write_area_plan`).
STAGING_PREFIX = ".area-plan."
_DISC_SIDES = 72


def flight_csv_name(number: int) -> str:
    """``flight_01.csv`` for flight 1."""
    return f"flight_{number:02d}.csv"


def orbit_rows(plan: AreaPlan, flight, position: int) -> list:
    """The Litchi rows of the ``position``-th orbit of ``flight``."""
    size = len(plan.orbit_plan.mission)
    return list(flight.mission.waypoints[position * size:(position + 1) * size])


def home_latlon(plan: AreaPlan) -> tuple[float, float]:
    """Take-off point, WGS84 degrees."""
    lat, lon, _ = plan.field.frame.to_geodetic(*plan.request.home_enu_m, 0.0)
    return float(lat), float(lon)


def _disc_lonlat(plan: AreaPlan, centre_enu: np.ndarray) -> np.ndarray:
    """The well-covered disc as a closed ``(_DISC_SIDES + 1, 2)`` ring of lon, lat."""
    angle = np.linspace(0.0, 2.0 * np.pi, _DISC_SIDES + 1)
    east = centre_enu[0] + plan.well_covered_radius_m * np.cos(angle)
    north = centre_enu[1] + plan.well_covered_radius_m * np.sin(angle)
    lat, lon, _ = plan.field.frame.to_geodetic(east, north, np.zeros_like(east))
    return np.stack([lon, lat], -1)


def _closed_field(plan: AreaPlan) -> np.ndarray:
    ring = np.stack([plan.field.lon_deg, plan.field.lat_deg], -1)
    return np.vstack([ring, ring[:1]])


def _flight_line(plan: AreaPlan, flight) -> np.ndarray:
    lat, lon = home_latlon(plan)
    stops = plan.centres_latlon_deg[list(flight.orbits)][:, ::-1]
    return np.vstack([[lon, lat], stops, [lon, lat]])


def _geometries(plan: AreaPlan):
    """``(kind, name, properties, geometry type, coordinates)`` of every overview feature, lon/lat degrees."""
    yield "field", "field", {"area_m2": plan.field.area_m2}, "Polygon", _closed_field(plan)
    for number, flight in enumerate(plan.flights, start=1):
        yield "flight", f"flight {number}", {"flight": number, "orbits": [i + 1 for i in flight.orbits]}, \
            "LineString", _flight_line(plan, flight)
        for position, index in enumerate(flight.orbits):
            rows = orbit_rows(plan, flight, position)
            ring = np.array([[w.longitude_deg, w.latitude_deg, w.altitude_m] for w in rows])
            props = {"orbit": index + 1, "flight": number, "covered_in_field_m2": float(plan.covered_in_field_m2[index])}
            yield "orbit", f"orbit {index + 1}", props, "LineString", ring
            yield "disc", f"orbit {index + 1} well covered", props, "Polygon", \
                _disc_lonlat(plan, plan.centres_enu_m[index])


def overview_geojson(plan: AreaPlan) -> dict:
    """RFC 7946 FeatureCollection of the field, the flights' order, the orbits and their well-covered discs."""
    features = []
    for kind, name, properties, geometry, coordinates in _geometries(plan):
        coordinates = coordinates.tolist()
        features.append({
            "type": "Feature",
            "properties": {"kind": kind, "name": name, **properties},
            "geometry": {"type": geometry, "coordinates": [coordinates] if geometry == "Polygon" else coordinates},
        })
    return {"type": "FeatureCollection", "features": features}


def overview_kml(plan: AreaPlan) -> str:
    """KML document with one folder per kind of feature (field, flights, orbits, discs)."""
    kml = ET.Element("kml", xmlns=KML_NAMESPACE)
    document = ET.SubElement(kml, "Document")
    ET.SubElement(document, "name").text = f"area plan of {Path(plan.field.source).name}"
    folders = {}
    for kind, name, _, geometry, coordinates in _geometries(plan):
        if kind not in folders:
            folders[kind] = ET.SubElement(document, "Folder")
            ET.SubElement(folders[kind], "name").text = kind
        placemark = ET.SubElement(folders[kind], "Placemark")
        ET.SubElement(placemark, "name").text = name
        if geometry == "Polygon":
            shape = ET.SubElement(ET.SubElement(ET.SubElement(placemark, "Polygon"), "outerBoundaryIs"), "LinearRing")
        else:
            shape = ET.SubElement(placemark, "LineString")
            ET.SubElement(shape, "altitudeMode").text = "relativeToGround"
        ET.SubElement(shape, "coordinates").text = coordinates_text(coordinates)
    ET.indent(kml)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(kml, encoding="unicode") + "\n"


def write_overview_png(plan: AreaPlan, path: Path) -> Path:
    """Top view in the field's ENU plane: field, discs, orbit centres numbered, and the flights' order."""
    figure = Figure(figsize=(8, 8), dpi=100, layout="constrained")
    axes = figure.subplots()
    field = np.vstack([plan.field.enu_m, plan.field.enu_m[:1]])
    axes.fill(field[:, 0], field[:, 1], color="tab:green", alpha=0.15, label="field")
    angle = np.linspace(0.0, 2.0 * np.pi, _DISC_SIDES + 1)
    home = np.asarray(plan.request.home_enu_m)
    colours = [f"C{k % 10}" for k in range(len(plan.flights))]
    for number, (flight, colour) in enumerate(zip(plan.flights, colours), start=1):
        centres = plan.centres_enu_m[list(flight.orbits)]
        line = np.vstack([home, centres, home])
        axes.plot(line[:, 0], line[:, 1], "-", color=colour, lw=0.8)
        for index, centre in zip(flight.orbits, centres):
            axes.plot(centre[0] + plan.well_covered_radius_m * np.cos(angle),
                      centre[1] + plan.well_covered_radius_m * np.sin(angle), color=colour, lw=0.4)
            axes.annotate(f"{number}.{index + 1}", centre, fontsize=6, ha="center", va="center")
    axes.plot(*home, "*", color="tab:red", ms=12, label="take-off")
    axes.set_aspect("equal")
    axes.set_xlabel("east (m)")
    axes.set_ylabel("north (m)")
    axes.set_title(f"{len(plan.centres_enu_m)} orbits in {len(plan.flights)} flights over "
                   f"{plan.field.area_m2:,.0f} m² (labels flight.orbit; circles: well covered)", fontsize=9)
    axes.grid(True, lw=0.3)
    axes.legend(loc="upper right", fontsize=8)
    with atomic_path(path) as temporary:
        figure.savefig(temporary, format="png")
    return Path(path)


def summary_dict(plan: AreaPlan, warnings: list[str]) -> dict:
    """JSON-ready derivation, orbits, flights and totals (``area.json``)."""
    orbit = plan.orbit_plan
    return {
        "field": {"source": plan.field.source, "area_m2": plan.field.area_m2, "perimeter_m": plan.field.perimeter_m,
                  "vertices": len(plan.field.enu_m), "origin": plan.field.frame.to_dict()},
        "take_off": dict(zip(("lat_deg", "lon_deg"), home_latlon(plan))),
        "heights": "metres above take-off (Litchi altitude mode 0)",
        "orbit": {k: v for k, v in orbit.summary_dict()["parameters"].items() if not k.startswith("center_")}
        | {"waypoints": len(orbit.mission), "flight_time_s": orbit.flight_time_s, "photo_count": orbit.photo_count},
        "well_covered_radius_m": plan.well_covered_radius_m,
        "overlap": plan.request.overlap,
        "spacing_m": plan.spacing_m,
        "transit_speed_m_s": plan.request.transit_speed_m_s,
        "field_coverage": plan.field_coverage,
        "orbits": [{"orbit": k + 1, "lat_deg": float(lat), "lon_deg": float(lon),
                    "east_m": float(e), "north_m": float(n), "covered_in_field_m2": float(a)}
                   for k, ((lat, lon), (e, n), a) in enumerate(zip(plan.centres_latlon_deg, plan.centres_enu_m,
                                                                    plan.covered_in_field_m2))],
        "flights": [{"flight": number, "csv": flight_csv_name(number), "orbits": [i + 1 for i in f.orbits],
                     "waypoints": len(f.mission), "photo_count": f.photo_count, "flight_time_s": f.flight_time_s,
                     "transit_m": f.transit_m, "batteries": 1,
                     "battery_used": f.flight_time_s / DJI_MINI_SE.usable_flight_time_s}
                    for number, f in enumerate(plan.flights, start=1)],
        "totals": {"orbits": len(plan.centres_enu_m), "flights": len(plan.flights), "batteries": len(plan.flights),
                   "photo_count": sum(f.photo_count for f in plan.flights),
                   "flight_time_s": sum(f.flight_time_s for f in plan.flights),
                   "transit_m": plan.transit_m, "transit_lower_bound_m": plan.transit_lower_bound_m,
                   "naive_order_transit_m": plan.naive_transit_m},
        "warnings": warnings,
    }


def summary_text(plan: AreaPlan) -> str:
    """The tables printed on stdout: the derivation, one row per flight, one per orbit, and the totals."""
    data = summary_dict(plan, [])
    totals = data["totals"]
    lines = [
        f"field {plan.field.area_m2:,.0f} m² ({len(plan.field.enu_m)} vertices); orbit r={plan.request.radius_m:g} m "
        f"h={plan.request.height_m:g} m covers a disc of {plan.well_covered_radius_m:.1f} m well; "
        f"overlap {plan.request.overlap:g} -> spacing {plan.spacing_m:.1f} m; field covered {100 * plan.field_coverage:.1f} %",
        f"flight  orbits      waypoints  photos  time_min  battery (of {DJI_MINI_SE.usable_flight_time_s / 60:.0f} min)  transit_m",
    ]
    for flight in data["flights"]:
        lines.append(f"{flight['flight']:>6}  {','.join(map(str, flight['orbits'])):<10}  {flight['waypoints']:>9}  "
                     f"{flight['photo_count']:>6}  {flight['flight_time_s'] / 60:>8.1f}  {'1 (' + format(flight['battery_used'], '.0%') + ')':>18}  "
                     f"{flight['transit_m']:>9.0f}")
    lines.append("orbit  flight  lat_deg      lon_deg       covered_in_field_m2")
    flight_of = {o: f["flight"] for f in data["flights"] for o in f["orbits"]}
    for orbit in data["orbits"]:
        lines.append(f"{orbit['orbit']:>5}  {flight_of[orbit['orbit']]:>6}  {orbit['lat_deg']:<11.7f}  "
                     f"{orbit['lon_deg']:<12.7f}  {orbit['covered_in_field_m2']:>19.0f}")
    lines.append(
        f"total  {totals['orbits']} orbits, {totals['flights']} flights = batteries, {totals['photo_count']} photos, "
        f"{totals['flight_time_s'] / 3600:.2f} h flying; transit {totals['transit_m']:.0f} m (lower bound "
        f"{totals['transit_lower_bound_m']:.0f} m, x{totals['transit_m'] / totals['transit_lower_bound_m']:.2f}; "
        f"row-by-row order {totals['naive_order_transit_m']:.0f} m)")
    return "\n".join(lines)


def write_area_plan(plan: AreaPlan, folder: Path, warnings: list[str]) -> list[Path]:
    """Write every flight's CSV and the overview into ``folder`` (created if absent); return the paths.

    Everything is written first into a hidden staging folder inside ``folder`` (:data:`STAGING_PREFIX`), then
    renamed into place, ``area.json`` last. A write that fails (a full disk, Ctrl-C) removes the staging folder,
    the files already moved and ``folder`` if this call created it; a run killed while writing leaves only the
    staging folder, which the next run removes (:func:`remove_stale_staging`): no half plan blocks the rerun.
    """
    created = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    remove_stale_staging(folder)
    staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, suffix=TEMP_MARK, dir=folder))
    moved: list[Path] = []
    try:
        names = [write().name for write in _plan_writes(plan, staging, warnings)]
        for name in names:  # area.json, written last, is moved in last
            os.replace(staging / name, folder / name)
            moved.append(folder / name)
        staging.rmdir()
    except BaseException as error:
        shutil.rmtree(staging, ignore_errors=True)
        for path in moved:
            path.unlink(missing_ok=True)
        if created and not any(folder.iterdir()):
            folder.rmdir()
        if isinstance(error, OSError) and error.filename and Path(error.filename).parent == staging:
            final = folder / Path(error.filename).name  # the name the user asked for, not the staging one
            raise type(error)(error.errno, error.strerror, str(final)) from error
        raise
    return moved


def _plan_writes(plan: AreaPlan, folder: Path, warnings: list[str]) -> list:
    """One call per file of the plan in ``folder``, in order (``area.json``, the summary, last); each returns the
    path it wrote."""
    kml, geojson, png, summary = (folder / name for name in OVERVIEW_NAMES)
    return [*(lambda n=n, f=f: write_mission_csv(f.mission, folder / flight_csv_name(n))
              for n, f in enumerate(plan.flights, start=1)),
            lambda: write_text_atomic(kml, overview_kml(plan)),
            lambda: write_text_atomic(geojson, json.dumps(overview_geojson(plan), indent=1) + "\n"),
            lambda: write_overview_png(plan, png),
            lambda: write_text_atomic(summary, json.dumps(summary_dict(plan, warnings), indent=2) + "\n")]


def remove_stale_staging(folder: Path) -> None:
    """Delete the staging folders that killed runs of :func:`write_area_plan` left in ``folder``."""
    for stale in folder.glob(f"{STAGING_PREFIX}*{TEMP_MARK}"):
        if stale.is_dir() and not stale.is_symlink():
            shutil.rmtree(stale)
