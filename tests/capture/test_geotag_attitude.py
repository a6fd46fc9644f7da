"""A geotag's attitude against what the aircraft can do (issue 40, left from the last round): aircraft tilt beyond
the DJI Mini SE's limit, gimbal pitch beyond its mechanical stops, a camera turning faster than the aircraft
can between photos. Such a photo is tagged from its own EXIF GPS and XMP (``source`` ``photo_exif``), named with
the reason, like a photo in a stretch of track no aircraft can fly."""

from __future__ import annotations

import re

import numpy as np
import pytest

from capture.attitude import wrap_deg
from capture.flyable import TILT_MARGIN_DEG
from capture.geotag import PHOTO_SOURCE, geotag_photos
from capture.synthetic import Noise, Orbit, photos_for, shutter_times, telemetry
from capture.track import Track
from flightplan.aircraft import DJI_MINI_SE
from flightplan.demo_location import DEMO_ORIGIN


def orbit_with(column: str, change, interval_s: float = 1.0, photo: int = 20):
    """A 60 s synthetic orbit whose track ``column`` is ``change(values)`` within 0.3 s of photo ``photo``'s
    shutter; the photos (own GPS, no XMP attitude) and that photo's name."""
    rng = np.random.default_rng(11)
    orbit = Orbit(DEMO_ORIGIN)
    shutter = shutter_times(orbit, 60.0, interval_s, Noise(), rng)
    track = telemetry(orbit, 60.0, 10.0, Noise(), rng, shutter)
    near = np.abs(track.time_s - shutter[photo]) < 0.3
    columns = dict(track.columns)
    columns[column] = np.where(near, change(columns[column]), columns[column])
    changed = Track.from_rows(track.time_s, columns, track.report, photo_times_s=track.photo_times_s)
    photos = photos_for(shutter, 0.37, orbit)
    return photos, changed, photos[photo].name


@pytest.mark.parametrize("column, change, reason", [
    ("aircraft_roll_deg", lambda v: v + DJI_MINI_SE.max_tilt_deg + TILT_MARGIN_DEG + 5.0,
     r"roll .* no DJI Mini SE tilts"),
    ("aircraft_pitch_deg", lambda v: v - 60.0, r"pitch -6\d\.\d .* no DJI Mini SE tilts"),
    ("gimbal_pitch_deg", lambda v: np.full_like(v, 60.0), r"gimbal pitch 60\.0 deg is beyond .* -110 \.\. 35 deg"),
])
def test_an_attitude_no_aircraft_can_have_falls_back_to_the_photos_own(column, change, reason):
    photos, track, odd = orbit_with(column, change)
    result = geotag_photos(photos, [track])
    assert [name for name, _ in result.from_photos] == [odd]
    assert re.search(reason, result.from_photos[0][1]), result.from_photos
    tag = next(tag for tag in result.tags if tag.image_name == odd)
    assert tag.source == PHOTO_SOURCE and len(result.tags) == len(photos)
    assert any("attitude from the logs is beyond what a DJI Mini SE can do" in note for note in result.notes)


def test_a_camera_that_turns_faster_than_the_aircraft_can():
    """Photos 0.5 s apart; the track's yaw turned 180 deg around one of them: 356 deg/s from both neighbours."""
    photos, track, odd = orbit_with("gimbal_yaw_deg", lambda v: wrap_deg(v + 180.0), interval_s=0.5)
    result = geotag_photos(photos, [track])
    assert [name for name, _ in result.from_photos] == [odd]
    assert "deg/s from its neighbours' attitude, faster than the 250 deg/s" in result.from_photos[0][1]


def test_the_default_orbit_keeps_every_attitude():
    """The orbit as flown (pitch -2, roll 1.5 deg, gimbal -31 deg, 0.8 deg/s): no photo flagged."""
    photos, track, _ = orbit_with("aircraft_roll_deg", lambda v: v)
    assert geotag_photos(photos, [track]).from_photos == []
