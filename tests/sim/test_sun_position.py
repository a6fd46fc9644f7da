"""The real sun: positions against published values and geometry that must hold (equinox, polar night, the
midnight sun, the southern hemisphere), and the clear-sky strength against Meinel's published irradiances."""

from __future__ import annotations

import datetime as dt

import pytest

from sim.sampling.sun import clear_sky_strength, solar_position

UTC = dt.timezone.utc


def test_nrel_spa_published_example():
    """Reda & Andreas (2003), NREL/TP-560-34302, table A5.1: Golden, Colorado, 2003-10-17 12:30:30 local (UTC-7):
    topocentric azimuth 194.34024 deg, zenith 50.11162 deg (refracted at 820 hPa and 11 C). Our standard atmosphere
    (1013.25 hPa, 12 C) lifts a 40 deg sun 0.004 deg more than theirs."""
    azimuth, elevation = solar_position(39.742476, -105.1786, dt.datetime(2003, 10, 17, 19, 30, 30, tzinfo=UTC))
    assert azimuth == pytest.approx(194.34024, abs=0.005)
    assert elevation == pytest.approx(90.0 - 50.11162 + 0.004, abs=0.005)


def test_equinox_sun_at_local_solar_noon_on_the_equator_is_at_the_zenith():
    """March equinox 2026 (20 March 14:46 UTC); at 0 N 0 E solar noon is 12:07 UTC (equation of time -7.4 min)."""
    _, elevation = solar_position(0.0, 0.0, dt.datetime(2026, 3, 20, 12, 7, tzinfo=UTC))
    assert elevation > 89.8


def test_polar_night_at_80_north_in_december():
    """At the December solstice the sun culminates at 90 - 80 - 23.44 = -13.4 deg at 80 N: below all day."""
    elevations = [solar_position(80.0, 15.0, dt.datetime(2026, 12, 21, hour, 0, tzinfo=UTC))[1] for hour in range(24)]
    assert max(elevations) == pytest.approx(-13.4, abs=0.3)


def test_midnight_sun_stands_due_north_and_azimuth_wraps_into_0_360():
    """At 80 N on the June solstice at local midnight the sun is due north at 80 + 23.44 - 90 = 13.4 deg (plus
    refraction): an azimuth near 0 deg must come out near 0 or near 360, never negative."""
    azimuths = []
    for minute in range(-20, 21, 4):  # through solar midnight at 0 E (00:02 UTC)
        utc = dt.datetime(2026, 6, 21, 0, 2, tzinfo=UTC) + dt.timedelta(minutes=minute)
        azimuth, elevation = solar_position(80.0, 0.0, utc)
        assert 0.0 <= azimuth < 360.0 and elevation == pytest.approx(13.5, abs=0.2)
        azimuths.append(azimuth)
    assert min(azimuths) < 5.0 and max(azimuths) > 355.0  # it passes north: the wrap is crossed


def test_noon_sun_is_south_in_the_north_and_north_in_the_south():
    noon = dt.datetime(2026, 6, 21, 12, 2, tzinfo=UTC)
    north_azimuth, north_elevation = solar_position(45.0, 0.0, noon)
    south_azimuth, south_elevation = solar_position(-45.0, 0.0, noon)
    assert north_azimuth == pytest.approx(180.0, abs=1.0) and north_elevation == pytest.approx(68.4, abs=0.1)
    assert min(south_azimuth, 360.0 - south_azimuth) < 1.0 and south_elevation == pytest.approx(21.6, abs=0.1)


def test_a_time_is_one_instant_whatever_its_zone():
    utc = dt.datetime(2026, 6, 1, 6, 30, tzinfo=UTC)
    tokyo = utc.astimezone(dt.timezone(dt.timedelta(hours=9)))
    assert solar_position(47.4, 8.5, tokyo) == solar_position(47.4, 8.5, utc)
    assert solar_position(47.4, 8.5, utc.replace(tzinfo=None)) == solar_position(47.4, 8.5, utc)  # naive = UTC


def test_clear_sky_strength_follows_meinels_published_irradiances():
    """Meinel & Meinel's direct beam: 947 W/m^2 at air mass 1 (the zenith), 764 at air mass 2 (30 deg), about 20
    at the horizon (air mass 38); the zenith sun is the paper's strongest, 10."""
    assert clear_sky_strength(90.0) == pytest.approx(10.0)
    assert clear_sky_strength(30.0) == pytest.approx(10.0 * 764 / 947, abs=0.05)
    assert clear_sky_strength(0.01) == pytest.approx(10.0 * 20 / 947, abs=0.05)
    assert clear_sky_strength(0.0) == clear_sky_strength(-5.0) == 0.0
    strengths = [clear_sky_strength(elevation) for elevation in range(1, 91)]
    assert strengths == sorted(strengths)
