"""The virtual drone's photos under the real sun: each photo's sun is the one over the scene at its own UTC time
(start + flight time), moving with it; truth.json records it per photo and at the flight's start and end; a photo
whose sun is down is refused before anything is written, for a later flight of an area plan too; ``--sun`` lights
every photo alike."""

from __future__ import annotations

import datetime as dt
import json

import numpy as np
import pytest

from sim.drone.session import FlyOptions, run_flights, run_session
from sim.render.scene import load_scene
from sim.sampling.light import SunSetting
from sim.sampling.sun import clear_sky_strength, solar_position
from sim.worlds import demo_scene_dir
from tests.sim.drone_helpers import short_orbit_csv

UTC = dt.timezone.utc
#: 06:00 UTC over the demo world (40.18 N, 44.50 E) on 1 June: mid-morning, the sun climbing about 0.2 deg a minute.
MORNING = dt.datetime(2026, 6, 1, 6, 0, tzinfo=UTC)


@pytest.fixture(scope="module")
def world():
    return load_scene(demo_scene_dir("small"))


def options(**changes) -> FlyOptions:
    return FlyOptions(photo_size=(32, 24), seed=1, photo_limit=2, progress=False, **changes)


def sunset(origin, day: dt.datetime) -> dt.datetime:
    """The UTC when the apparent sun sets over ``origin`` on ``day`` (bisection on its elevation, to 1 s)."""
    early, late = day.replace(hour=14), day.replace(hour=18)  # 18:00-22:00 local time in Armenia
    while late - early > dt.timedelta(seconds=1):
        middle = early + (late - early) / 2
        if solar_position(origin.lat0_deg, origin.lon0_deg, middle)[1] > 0:
            early = middle
        else:
            late = middle
    return late


def test_each_photo_has_the_real_sun_of_its_own_time(world, tmp_path):
    report = run_session(short_orbit_csv(tmp_path / "orbit.csv"), world, tmp_path / "fly", options(start_utc=MORNING))
    truth = json.loads((tmp_path / "fly" / "truth.json").read_text())
    origin = world.origin
    for photo in truth["photos"]:
        azimuth, elevation = solar_position(origin.lat0_deg, origin.lon0_deg,
                                            MORNING + dt.timedelta(seconds=photo["t_s"]))
        assert photo["sun"] == {"azimuth_deg": azimuth, "elevation_deg": elevation,
                                "strength": clear_sky_strength(elevation)}
    first, last = truth["photos"][0], truth["photos"][-1]
    minutes = (last["t_s"] - first["t_s"]) / 60.0
    climbed = (last["sun"]["elevation_deg"] - first["sun"]["elevation_deg"]) / minutes
    assert 0.15 < climbed < 0.25  # deg/min: 15 deg/h along a path tilted by the latitude, climbing steeply in June
    top = truth["sun"]
    assert top["form"] == "time" and top["start"]["utc"] == "2026-06-01T06:00:00Z"
    assert top["start"]["elevation_deg"] < first["sun"]["elevation_deg"] < last["sun"]["elevation_deg"] \
        < top["end"]["elevation_deg"]
    assert report.sun == top


def test_a_given_sun_lights_every_photo_alike(world, tmp_path):
    run_session(short_orbit_csv(tmp_path / "orbit.csv"), world, tmp_path / "fly",
                options(start_utc=MORNING.replace(hour=22), sun=SunSetting("fixed", 150.0, 50.0, 10.0)))
    truth = json.loads((tmp_path / "fly" / "truth.json").read_text())
    assert truth["sun"] == {"form": "fixed", "azimuth_deg": 150.0, "elevation_deg": 50.0, "strength": 10.0,
                            "linear_intensity": 1.0}
    assert all("sun" not in photo for photo in truth["photos"])  # it does not move: once, at the top


def test_a_photo_with_the_sun_down_is_refused_before_anything_is_written(world, tmp_path):
    night = MORNING.replace(hour=21)
    with pytest.raises(ValueError, match=r"photo DJI_0001\.JPG: at 2026-06-01T21:00:\d\d(\.\d+)?Z the sun is at "
                                         r"-2\d\.\d deg elevation over 40\.17920, 44\.49910 .* give a daytime "
                                         r"--start-utc or --sun"):
        run_session(short_orbit_csv(tmp_path / "orbit.csv"), world, tmp_path / "fly", options(start_utc=night))
    with pytest.raises(ValueError, match=r"^--sun time:2026-06-01T21:00:00Z: photo DJI_0001\.JPG: .* up there"):
        run_session(tmp_path / "orbit.csv", world, tmp_path / "fly", options(sun=SunSetting("time", utc=night)))
    assert not (tmp_path / "fly").exists()


def test_an_area_plan_is_refused_whole_when_a_later_flight_would_fly_after_sunset(world, tmp_path):
    """Flight 1 (76 s) ends two minutes before sunset; flight 2 takes off 5 min later, in the dark."""
    mission = short_orbit_csv(tmp_path / "orbit.csv")
    start = sunset(world.origin, MORNING) - dt.timedelta(seconds=200)
    with pytest.raises(ValueError, match=r"orbit\.csv \(flight 2\): photo DJI_0001\.JPG: .* at or below the horizon"):
        run_flights([mission, mission], world, tmp_path / "flights", options(start_utc=start))
    assert not (tmp_path / "flights").exists()
    reports = run_flights([mission], world, tmp_path / "one", options(start_utc=start))
    assert 0 < reports[0].sun["end"]["elevation_deg"] < 1.0
    assert np.isfinite(reports[0].rendered.gains).any()
