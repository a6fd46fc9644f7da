"""Each photo's capture sun (recon/appearance/capture_sun.py): the ephemeris's sun at the photo's UTC over the scene, a
unit direction towards it, nothing for a sun below the horizon or a photo set without times."""

import datetime as dt
import math

import numpy as np
import pytest

from flightplan.geodesy import LocalFrame
from recon.appearance.capture_sun import capture_suns, is_timed
from sim.sampling.sun import solar_position

ZURICH = LocalFrame(47.3769, 8.5417, 400.0)


def utc(text: str) -> float:
    return dt.datetime.fromisoformat(text).replace(tzinfo=dt.timezone.utc).timestamp()


def test_each_photo_gets_the_sun_at_its_own_time():
    times = np.array([utc("2026-06-21T09:00:00"), utc("2026-06-21T11:30:00"), utc("2026-06-21T23:00:00")])
    suns = capture_suns(["a.jpg", "b.jpg", "c.jpg"], times, ZURICH, "geotags")
    for k, t in enumerate(times):
        expected = solar_position(ZURICH.lat0_deg, ZURICH.lon0_deg, dt.datetime.fromtimestamp(t, dt.timezone.utc))
        assert (suns.azimuth_deg[k], suns.elevation_deg[k]) == expected
    assert 90 < suns.azimuth_deg[0] < 180 and suns.elevation_deg[1] > suns.elevation_deg[0] > 0
    directions = suns.directions_enu
    np.testing.assert_allclose(np.linalg.norm(directions[:2], axis=1), 1.0)
    assert math.degrees(math.asin(directions[1, 2])) == pytest.approx(suns.elevation_deg[1], abs=1e-9)
    np.testing.assert_array_equal(directions[2], 0.0)  # night: no sun to shadow anything
    reordered = suns.for_names(["c.jpg", "a.jpg"])
    assert reordered.names == ("c.jpg", "a.jpg") and reordered.azimuth_deg[1] == suns.azimuth_deg[0]
    assert set(suns.description()["per_photo"]) == {"a.jpg", "b.jpg", "c.jpg"}


def test_a_photo_set_with_any_untimed_photo_is_not_timed():
    assert is_timed(np.array([1.7e9, 1.7e9 + 1]))
    assert not is_timed(None) and not is_timed(np.array([1.7e9, math.nan])) and not is_timed(np.array([]))
