"""Previews: KML and GeoJSON carry the waypoints and the POI, split at the antimeridian; the PNG is a real image."""

import json

import numpy as np
from defusedxml import ElementTree
from PIL import Image

from flightplan import preview
from flightplan.orbit import OrbitRequest, plan_orbit

KML = "{http://www.opengis.net/kml/2.2}"


def test_kml_and_geojson_across_the_antimeridian(tmp_path):
    plan = plan_orbit(OrbitRequest(10.0, 179.9999))
    mission = plan.mission
    root = ElementTree.parse(preview.write_kml(mission, tmp_path / "m.kml")).getroot()
    placemarks = root.iter(f"{KML}Placemark")
    names = [p.find(f"{KML}name").text for p in placemarks]
    assert names.count("POI") == 1 and len([n for n in names if n.startswith("WP")]) == len(mission)
    lines = [
        np.array([[float(v) for v in c.split(",")] for c in line.find(f"{KML}coordinates").text.split()])
        for line in root.iter(f"{KML}LineString")
    ]
    assert len(lines) >= 2, "a circle around lon 179.9999 crosses the antimeridian and must be cut"
    for line in lines:
        assert np.all(np.abs(line[:, 0]) <= 180.0) and np.all(np.abs(np.diff(line[:, 0])) < 1.0)
        assert np.all(line[:, 2] == 30.0)
    data = json.loads(preview.write_geojson(mission, tmp_path / "m.geojson").read_text())
    path, *points = data["features"]
    assert path["geometry"]["type"] == "MultiLineString" and len(path["geometry"]["coordinates"]) == len(lines)
    assert points[-1]["properties"]["name"] == "POI"
    assert points[0]["geometry"]["coordinates"] == [mission.waypoints[0].longitude_deg, mission.waypoints[0].latitude_deg, 30.0]


def test_split_interpolates_the_crossing():
    pieces = preview.split_at_antimeridian(np.array([179.0, -179.0]), np.array([0.0, 2.0]), np.array([5.0, 5.0]))
    np.testing.assert_allclose(pieces[0][-1], [180.0, 1.0, 5.0])
    np.testing.assert_allclose(pieces[1][0], [-180.0, 1.0, 5.0])


def test_png_plot(tmp_path):
    plan = plan_orbit(OrbitRequest(40.1792, 44.4991))
    path = preview.write_plot_png(plan.mission, 40.1792, 44.4991, tmp_path / "plan.png")
    with Image.open(path) as image:
        assert image.format == "PNG" and image.size == (700, 700)
        pixels = np.asarray(image.convert("RGB"))
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 20  # something was drawn
