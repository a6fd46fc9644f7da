"""Area planning against known truth: coverage of a square field checked by sampling, battery and waypoint limits,
every flight's CSV re-read with the Litchi reader and checked, transit against a naive order and the lower bound,
the overview's polygon read back, and the well-covered radius against OpenCV's projection."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from flightplan import checks, litchi
from flightplan.aircraft import DJI_MINI_SE
from flightplan.area import (AreaRequest, WELL_SEEN_FRACTION, lattice_spacing_m, plan_area, transit_lower_bound_m,
                             well_covered_radius_m)
from cliutil.errors import BadInput
from flightplan.cli import main
from flightplan.field import field_from_lonlat, first_self_intersection, read_field
from flightplan.geodesy import LocalFrame

ORIGIN = LocalFrame(47.3769, 8.5417)


def square_lonlat(side_m: float, centre=(0.0, 0.0)) -> np.ndarray:
    """A square of ``side_m`` around ``centre`` (ENU m at ORIGIN) as lon, lat degrees."""
    half = side_m / 2.0
    east = centre[0] + np.array([-half, half, half, -half])
    north = centre[1] + np.array([-half, -half, half, half])
    lat, lon, _ = ORIGIN.to_geodetic(east, north, np.zeros(4))
    return np.stack([lon, lat], -1)


def write_geojson(path, lonlat) -> None:
    ring = [list(p) for p in lonlat] + [list(lonlat[0])]
    path.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [ring]}}]}))


@pytest.fixture(scope="module")
def square_plan():
    return plan_area(field_from_lonlat(square_lonlat(300.0), "square"), AreaRequest())


def test_square_area_is_the_geodesic_area():
    assert field_from_lonlat(square_lonlat(300.0), "square").area_m2 == pytest.approx(300.0 ** 2, rel=1e-6)


@pytest.mark.parametrize("width_m, planned", [(1.05, True), (0.95, False), (0.0, False)])
def test_a_field_narrower_than_a_metre_is_a_sliver(width_m, planned):
    """A 200 m strip: 1.05 m wide is a field (a road to cover), 0.95 m or three collinear points is none."""
    east = np.array([-100.0, 0.0, 100.0, 100.0, -100.0]) if width_m else np.array([-100.0, 0.0, 100.0])
    north = np.array([0.0, 0.0, 0.0, width_m, width_m]) if width_m else np.zeros(3)
    lat, lon, _ = ORIGIN.to_geodetic(east, north, np.zeros(len(east)))
    if planned:
        assert field_from_lonlat(np.stack([lon, lat], -1), "strip").area_m2 == pytest.approx(200.0 * width_m, rel=1e-3)
    else:
        with pytest.raises(BadInput, match=r"strip: the polygon encloses .* m² within its 40\d m boundary, a sliver"):
            field_from_lonlat(np.stack([lon, lat], -1), "strip")


def test_well_covered_discs_cover_a_square_field(square_plan):
    points = np.random.default_rng(0).uniform(-150.0, 150.0, (20000, 2))
    # the plan's centres are in the field's own ENU plane (centred on the square): map the samples there
    lat, lon, _ = ORIGIN.to_geodetic(points[:, 0], points[:, 1], np.zeros(len(points)))
    east, north, _ = square_plan.field.frame.to_enu(lat, lon, np.zeros(len(points)))
    distance = np.linalg.norm(np.stack([east, north], -1)[:, None] - square_plan.centres_enu_m[None], axis=2).min(axis=1)
    assert distance.max() <= square_plan.well_covered_radius_m
    assert square_plan.field_coverage == 1.0


def test_neighbours_share_the_requested_overlap(square_plan):
    centres = square_plan.centres_enu_m
    gaps = np.linalg.norm(centres[:, None] - centres[None], axis=2)
    nearest = np.sort(gaps, axis=1)[:, 1]
    expected = lattice_spacing_m(square_plan.well_covered_radius_m, 0.2)
    assert nearest == pytest.approx(expected, abs=1e-6)
    assert 2 * square_plan.well_covered_radius_m - expected == pytest.approx(0.2 * 2 * square_plan.well_covered_radius_m)


def test_well_covered_radius_matches_opencv_projection():
    """Count the orbit's photos that see a ground point with cv2.projectPoints just inside and outside the disc."""
    radius, height = 50.0, 30.0
    covered = well_covered_radius_m(DJI_MINI_SE.camera, radius, height)
    fx, fy, cx, cy = DJI_MINI_SE.camera.pinhole_intrinsics()
    matrix = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])

    def seen_fraction(ground_radius):
        seen = 0
        for azimuth in np.linspace(0.0, 2 * np.pi, 360, endpoint=False):
            position = np.array([radius * np.cos(azimuth), radius * np.sin(azimuth), height])
            forward = -position / np.linalg.norm(position)
            right = np.cross(forward, [0, 0, 1.0])
            right /= np.linalg.norm(right)
            rotation = np.stack([right, np.cross(forward, right), forward])  # rows: camera axes in world
            rvec, _ = cv2.Rodrigues(rotation)
            pixel, _ = cv2.projectPoints(np.array([[ground_radius, 0.0, 0.0]]), rvec, -rotation @ position, matrix, None)
            u, v = pixel[0, 0]
            seen += (rotation @ (np.array([ground_radius, 0, 0]) - position))[2] > 0 and -0.5 <= u <= 2 * cx + 0.5 \
                and -0.5 <= v <= 2 * cy + 0.5
        return seen / 360

    assert seen_fraction(covered - 0.5) >= WELL_SEEN_FRACTION > seen_fraction(covered + 0.5)
    assert 30.0 < covered < radius  # inside ~32 m every photo sees the point; the ring itself is seen by fewer


def test_flights_respect_battery_and_waypoint_limits(square_plan):
    orbit_rows = len(square_plan.orbit_plan.mission)
    assert sorted(i for f in square_plan.flights for i in f.orbits) == list(range(len(square_plan.centres_enu_m)))
    for flight in square_plan.flights:
        assert len(flight.mission) == orbit_rows * len(flight.orbits) <= litchi.MAX_WAYPOINTS
        assert flight.flight_time_s <= DJI_MINI_SE.usable_flight_time_s
        orbit_time = len(flight.orbits) * square_plan.orbit_plan.flight_time_s
        assert flight.flight_time_s == pytest.approx(orbit_time + flight.transit_m / square_plan.request.transit_speed_m_s)


def test_transit_beats_naive_order_and_respects_lower_bound(square_plan):
    assert square_plan.transit_lower_bound_m <= square_plan.transit_m <= square_plan.naive_transit_m


def test_lower_bound_is_exact_for_one_orbit_per_flight():
    centres = np.array([[100.0, 0.0], [0.0, 200.0]])
    assert transit_lower_bound_m(np.zeros(2), centres, 1) == pytest.approx(600.0)


def test_self_intersection_is_found():
    bowtie = np.array([[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]])
    assert first_self_intersection(bowtie) == (0, 2)
    assert first_self_intersection(np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])) is None


def test_cli_writes_checked_flights_and_an_overview_that_reads_back(tmp_path, capsys):
    lonlat = square_lonlat(120.0, centre=(500.0, -300.0))
    write_geojson(tmp_path / "field.geojson", lonlat)
    assert main(["--area", str(tmp_path / "field.geojson"), "--out", str(tmp_path / "plan"), "--interval", "2"]) == 0
    summary = json.loads((tmp_path / "plan" / "area.json").read_text())
    assert summary["field"]["area_m2"] == pytest.approx(120.0 ** 2, rel=1e-6)
    assert f"{summary['totals']['flights']} flights = batteries" in capsys.readouterr().out
    for flight in summary["flights"]:
        mission = litchi.read_mission_csv(tmp_path / "plan" / flight["csv"])
        assert len(mission) == flight["waypoints"]
        assert not [f for f in checks.check_mission(mission, DJI_MINI_SE, flight["flight_time_s"]) if f.severity == "error"]
    for name in ("area.kml", "area.geojson"):  # the overview's field polygon is the field read back
        field = read_field(tmp_path / "plan" / name)
        assert np.allclose(np.stack([field.lon_deg, field.lat_deg], -1), lonlat, atol=1e-12)


def test_google_earth_kml_reads_as_the_same_polygon_as_geojson(tmp_path):
    """A KML as Google Earth writes it (namespace, heights, a hole) gives the GeoJSON's exterior ring."""
    lonlat = square_lonlat(200.0)
    ring = " ".join(f"{float(lon)!r},{float(lat)!r},0" for lon, lat in [*lonlat, lonlat[0]])
    hole = " ".join(f"{float(lon)!r},{float(lat)!r},0" for lon, lat in square_lonlat(20.0))
    (tmp_path / "field.kml").write_text(
        '<?xml version="1.0" encoding="UTF-8"?><kml xmlns="http://www.opengis.net/kml/2.2" '
        'xmlns:gx="http://www.google.com/kml/ext/2.2"><Document><name>field</name><Placemark><name>f</name><Polygon>'
        f"<tessellate>1</tessellate><outerBoundaryIs><LinearRing><coordinates>\n\t{ring}\n</coordinates></LinearRing>"
        f"</outerBoundaryIs><innerBoundaryIs><LinearRing><coordinates>{hole}</coordinates></LinearRing>"
        "</innerBoundaryIs></Polygon></Placemark></Document></kml>")
    write_geojson(tmp_path / "field.geojson", lonlat)
    from_kml, from_geojson = read_field(tmp_path / "field.kml"), read_field(tmp_path / "field.geojson")
    assert np.array_equal(from_kml.lat_deg, from_geojson.lat_deg) and np.array_equal(from_kml.lon_deg, lonlat[:, 0])
    assert from_kml.area_m2 == pytest.approx(200.0 ** 2, rel=1e-6)
