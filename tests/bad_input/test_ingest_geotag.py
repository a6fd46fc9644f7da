"""``aerostereo-ingest geotag`` on hostile input: photos from another flight or place, outputs that name an input.

Each case must end with exit 2, one stderr line naming what was wrong (and how to force it, where it can be
forced), no traceback and no file left behind (:mod:`tests.bad_input.harness`).
"""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest
from PIL import Image

from tests.bad_input.harness import Case, assert_refused, run_case
from tests.capture.test_cli_logs import write_jpeg
from tests.capture.test_geotag_checks import yerevan_log
from tests.conftest import SHARED_DATA

MINNESOTA_PHOTOS = SHARED_DATA / "brighton_beach" / "images"
SEVEN_YEARS_S = 7.85 * 365.25 * 86400


def flight(tmp, *, camera_shift_s=0.0, north_shift_m=0.0, photos=8):
    """A Litchi log of the synthetic orbit around the demo origin (Yerevan, 2024) in ``tmp/flight.csv`` and
    ``photos`` JPEGs in ``tmp/photos`` whose EXIF time is moved by ``camera_shift_s`` and whose GPS is moved
    ``north_shift_m`` north of the track."""
    orbit, shutter = yerevan_log(tmp / "flight.csv", duration_s=30.0)
    shutter = shutter[:photos]
    (tmp / "photos").mkdir()
    east, north, _ = orbit.enu(shutter).T
    lat, lon, _ = orbit.frame.to_geodetic(east, north + north_shift_m, np.zeros(len(shutter)))
    for i, s in enumerate(shutter):
        write_jpeg(tmp / "photos" / f"DJI_{i:04d}.JPG", s - 0.37 + camera_shift_s, lat[i], lon[i])


def minnesota_photos_and_a_yerevan_log(tmp):
    if not MINNESOTA_PHOTOS.is_dir():
        pytest.skip(f"real sample data not found at {SHARED_DATA} (set AEROSTEREO_SHARED_DATA)")
    flight(tmp)
    shutil.rmtree(tmp / "photos")
    shutil.copytree(MINNESOTA_PHOTOS, tmp / "photos")


def flight_with_a_png_named_jpg(tmp):
    """The synthetic flight with DJI_0005.JPG re-saved as a PNG that keeps its EXIF (so it is geotagged, but its
    metadata cannot be edited as a JPEG's)."""
    flight(tmp)
    photo = tmp / "photos" / "DJI_0005.JPG"
    with Image.open(photo) as image:
        image.load()
        exif, pixels = image.getexif(), image.copy()
    pixels.save(photo, format="PNG", exif=exif)


def flight_and_a_file(tmp):
    """The synthetic flight and a file ``flight.csv.bak`` beside it."""
    flight(tmp)
    (tmp / "flight.csv.bak").write_text("x\n")


GEOTAG = ["geotag", "--photos", "{tmp}/photos", "--log", "{tmp}/flight.csv"]

CASES = [
    Case("geotag-minnesota-photos-yerevan-log", "aerostereo-ingest", [*GEOTAG, "--out", "{tmp}/g.csv"],
         r"7\.8\d years apart .*beyond the \+-14\.5 h .*--clock-offset", minnesota_photos_and_a_yerevan_log),
    Case("geotag-camera-clock-years-off", "aerostereo-ingest", [*GEOTAG, "--out", "{tmp}/g.csv"],
         r"at least 7\.8\d years apart .*--clock-offset SECONDS",
         lambda tmp: flight(tmp, camera_shift_s=-SEVEN_YEARS_S)),
    Case("geotag-camera-clock-a-day-off", "aerostereo-ingest", [*GEOTAG, "--out", "{tmp}/g.csv"],
         r"at least 24 h apart .*\+-14\.5 h", lambda tmp: flight(tmp, camera_shift_s=86400.0)),
    Case("geotag-photo-gps-elsewhere", "aerostereo-ingest", [*GEOTAG, "--out", "{tmp}/g.csv"],
         r"photos' own GPS is a median 4\.9\d\d km .*at every clock offset the shutter events allow .*more than the "
         r"9 m .*--clock-offset SECONDS .*--max-misfit 50\d\d",
         lambda tmp: flight(tmp, north_shift_m=5000.0)),
    Case("geotag-photo-gps-elsewhere-tighter-bound", "aerostereo-ingest",
         [*GEOTAG, "--out", "{tmp}/g.csv", "--max-misfit", "20"],
         r"GPS cannot tell the clock offset: .*beyond the 20 m .*--clock-offset SECONDS .*--max-misfit \d+",
         lambda tmp: flight(tmp, north_shift_m=30.0)),
    Case("geotag-forced-offset-elsewhere", "aerostereo-ingest",
         [*GEOTAG, "--out", "{tmp}/g.csv", "--clock-offset", "0.37"],
         r"median 4\.999 km", lambda tmp: flight(tmp, north_shift_m=5000.0)),
    Case("geotag-out-is-a-photo", "aerostereo-ingest", [*GEOTAG, "--out", "{tmp}/photos/DJI_0001.JPG"],
         r"--out .*DJI_0001\.JPG: is also --photos", flight),
    Case("geotag-out-is-the-log", "aerostereo-ingest", [*GEOTAG, "--out", "{tmp}/flight.csv"],
         r"--out .*flight\.csv: is also --log", flight),
    Case("geotag-write-exif-png-named-jpg", "aerostereo-ingest", [*GEOTAG, "--out", "{tmp}/g.csv", "--write-exif"],
         r"photos/DJI_0005\.JPG: not a JPEG \(no SOI marker\)", flight_with_a_png_named_jpg),
    Case("geotag-exif-dir-is-a-file", "aerostereo-ingest",
         [*GEOTAG, "--out", "{tmp}/g.csv", "--write-exif", "--exif-dir", "{tmp}/flight.csv.bak"],
         r"--exif-dir .*flight\.csv\.bak: is a file; expected a folder",
         flight_and_a_file),
    Case("geotag-colmap-ref-is-the-log", "aerostereo-ingest",
         [*GEOTAG, "--out", "{tmp}/g.csv", "--colmap-ref", "{tmp}/flight.csv"], r"--colmap-ref .*: is also --log",
         flight),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_the_misfit_bound_can_be_lifted(tmp_path):
    """The way out the refusal names works: --max-misfit above the stated distance accepts photos 5 km off, and
    the summary still says how far they were (5 km off, their GPS cannot tell which whole-second shift of a 1 s
    shutter pattern is right: a few metres either way)."""
    flight(tmp_path, north_shift_m=5000.0)
    case = Case("lifted", "aerostereo-ingest", [*GEOTAG, "--out", "{tmp}/g.csv", "--max-misfit", "6000"], "")
    result = run_case(case, tmp_path)
    assert result.code == 0 and re.search(r"photo GPS vs geotags from the logs: median 49\d\d\.", result.err)
    assert (tmp_path / "g.csv").read_text().count("\n") == 9
