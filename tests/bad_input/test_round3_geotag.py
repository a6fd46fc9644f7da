"""``aerostereo-ingest geotag`` on part of a flight (issue 40): where the photos' own GPS agrees with the logs at no
clock offset the shutter events allow, the geotagger refuses in one line naming --clock-offset and --max-misfit,
instead of settling on a whole-second shift tens of metres along the track with exit 0. A forced offset a whole
number of seconds off is refused the same way (the photos' GPS "off the logs as a whole" is no longer accepted
by default, so each photo's own-GPS check cannot be skipped on a wrong offset).

The card: the first 80 photos of the synthetic 1 s orbit around the demo origin (a Litchi log of 200 s).
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from tests.bad_input.harness import Case, assert_refused, run_case
from tests.capture.test_cli_logs import write_jpeg
from tests.capture.test_geotag_checks import yerevan_log

CAMERA_OFFSET_S = 0.37  # telemetry UTC - camera clock


def first_80_photos(tmp, *, east_shift_m=0.0, radius_scale=1.0):
    """A 200 s Litchi log ``tmp/flight.csv`` and its first 80 photos in ``tmp/photos``, their own GPS moved
    ``east_shift_m`` east and ``radius_scale`` times as far from the orbit's centre as the track puts them."""
    orbit, shutter = yerevan_log(tmp / "flight.csv", duration_s=200.0)
    shutter = shutter[:80]
    (tmp / "photos").mkdir()
    east, north, _ = orbit.enu(shutter).T
    lat, lon, _ = orbit.frame.to_geodetic(east * radius_scale + east_shift_m, north * radius_scale,
                                          np.zeros(len(shutter)))
    for i, s in enumerate(shutter):
        write_jpeg(tmp / "photos" / f"DJI_{i:04d}.JPG", s - CAMERA_OFFSET_S, lat[i], lon[i])


GEOTAG = ["geotag", "--photos", "{tmp}/photos", "--log", "{tmp}/flight.csv", "--out", "{tmp}/g.csv"]
REFUSAL = (r"photos' own GPS is a median [\d.]+ m .*from the logs' track at every clock offset the shutter events "
           r"allow .*more than the 9 m .*give --clock-offset SECONDS .*--max-misfit \d+")

CASES = [
    # another flight at the same place: photos of a 70 m orbit against the log of a 50 m one
    Case("geotag-subset-photos-of-a-wider-orbit", "aerostereo-ingest", GEOTAG, REFUSAL,
         lambda tmp: first_80_photos(tmp, radius_scale=1.4)),
    # the photos' GPS is 25 m off the logs' (another receiver, a datum shift): stated, with the way out
    Case("geotag-subset-photo-gps-25-m-off", "aerostereo-ingest", GEOTAG, REFUSAL,
         lambda tmp: first_80_photos(tmp, east_shift_m=25.0)),
    # the pattern fits a whole-second shift as well; forced by hand, the photos' GPS refuses it
    Case("geotag-subset-forced-whole-second-shift", "aerostereo-ingest", [*GEOTAG, "--clock-offset", "60.37"],
         r"photos' own GPS is a median [\d.]+ m .*at their matched times, more than the 9 m .*or the clock offset "
         r"is wrong; give --max-misfit \d+", first_80_photos),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_the_same_card_with_its_own_gps_is_tagged(tmp_path):
    """The valid counterpart: the same 80 photos with their true GPS are tagged at the camera's offset."""
    first_80_photos(tmp_path)
    result = run_case(Case("valid", "aerostereo-ingest", GEOTAG, ""), tmp_path)
    assert result.code == 0 and "80 photos geotagged, 0 untagged" in result.out, result.err
    offset, std = map(float, re.search(r"clock offset ([-+\d.]+) \+- ([\d.]+) s \(auto", result.err).groups())
    assert abs(offset - CAMERA_OFFSET_S) < min(3 * std + 0.02, 1.0), result.err  # no whole-second shift
    assert "photo GPS vs geotags from the logs: median 0.0" in result.err, result.err
