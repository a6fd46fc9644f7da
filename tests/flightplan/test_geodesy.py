"""Geodesy against GeographicLib and round trips, including the hard places on the globe."""

import numpy as np
import pytest
from geographiclib.geodesic import Geodesic

from flightplan.geodesy import LocalFrame, geodesic_direct, geodesic_inverse, wrap_lon_deg

HARD_ORIGINS = [
    (0.0, 0.0, 0.0),  # equator / prime meridian
    (89.99, 10.0, 50.0),  # near the north pole
    (-89.99, -120.0, 0.0),  # near the south pole
    (10.0, 179.9999, 0.0),  # antimeridian
    (-33.9, -179.9999, 500.0),
    (47.3769, 8.5417, 408.0),
]


@pytest.mark.parametrize("origin", HARD_ORIGINS)
def test_round_trip_million_points(origin):
    frame = LocalFrame(*origin)
    rng = np.random.default_rng(1)
    n = 1_000_000
    east, north, up = (rng.uniform(-5000, 5000, n), rng.uniform(-5000, 5000, n), rng.uniform(-10, 500, n))
    lat, lon, h = frame.to_geodetic(east, north, up)
    e2, n2, u2 = frame.to_enu(lat, lon, h)
    assert np.abs(e2 - east).max() < 1e-3
    assert np.abs(n2 - north).max() < 1e-3
    assert np.abs(u2 - up).max() < 1e-3
    lat3, lon3, h3 = frame.to_geodetic(e2, n2, u2)
    assert np.abs(lat3 - lat).max() < 1e-9
    assert np.abs(wrap_lon_deg(lon3 - lon)).max() < 1e-9
    assert np.abs(h3 - h).max() < 1e-3


def test_origin_maps_to_zero_and_up_is_up():
    frame = LocalFrame(47.0, 8.0, 400.0)
    e, n, u = frame.to_enu(47.0, 8.0, 430.0)
    assert abs(e) < 1e-9 and abs(n) < 1e-9 and abs(u - 30.0) < 1e-9


def test_enu_distance_matches_geodesic_over_short_range():
    frame = LocalFrame(54.37, 18.56, 0.0)
    dest = geodesic_direct(54.37, 18.56, 60.0, 100.0)
    e, n, _ = frame.to_enu(dest.lat_deg, dest.lon_deg, 0.0)
    assert np.hypot(e, n) == pytest.approx(100.0, abs=2e-3)
    assert np.degrees(np.arctan2(e, n)) == pytest.approx(60.0, abs=1e-3)


def test_geodesic_direct_inverse_agree_with_geographiclib():
    ref = Geodesic.WGS84.Direct(-33.0, 179.99, 135.0, 5000.0)
    p = geodesic_direct(-33.0, 179.99, 135.0, 5000.0)
    assert p.lat_deg == pytest.approx(ref["lat2"], abs=1e-12)
    assert p.lon_deg == pytest.approx(float(wrap_lon_deg(ref["lon2"])), abs=1e-12)
    line = geodesic_inverse(-33.0, 179.99, p.lat_deg, p.lon_deg)
    assert line.distance_m == pytest.approx(5000.0, abs=1e-6)
    assert line.azimuth1_deg == pytest.approx(135.0, abs=1e-9)


@pytest.mark.parametrize("bad", [(91.0, 0.0), (float("nan"), 0.0), (0.0, 400.0)])
def test_bad_origin_is_rejected(bad):
    with pytest.raises(ValueError):
        LocalFrame(*bad)


@pytest.mark.parametrize("target", [LocalFrame(40.1800, 44.5000, 1003.0), LocalFrame(40.2100, 44.4500, 900.0)])
def test_transform_to_matches_geodetic_round_trip_within_a_millimetre(target):
    source = LocalFrame(40.1792, 44.4991, 1000.0)
    points_enu_m = np.random.default_rng(3).uniform(-2000.0, 2000.0, size=(200, 3)) * [1, 1, 0.1]
    transform = source.transform_to(target)
    moved = points_enu_m @ transform[:3, :3].T + transform[:3, 3]
    expected = target.enu_points(*source.to_geodetic(*points_enu_m.T))
    assert np.abs(moved - expected).max() < 1e-3
    assert np.allclose(transform[:3, :3] @ transform[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.allclose(source.transform_to(source), np.eye(4), atol=1e-8)
