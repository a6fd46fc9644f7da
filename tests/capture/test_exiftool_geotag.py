"""The README's exiftool recipe run for real on the virtual drone's photos (sub-second EXIF times, DJI heights)
geotagged from its DUML capture, and the absolute heights our GPX gives exiftool, from a DUML capture (its home
point) and from a Litchi log (the photos' own heights), against the known geoid undulation between them."""

from __future__ import annotations

import datetime as dt
import json
import re
import shlex
import shutil

import numpy as np
import pytest
from defusedxml import ElementTree as SafeET

from capture.cli import main as ingest
from capture.geotag_io import load_geotags
from capture.logs.photos import read_photo
from flightplan.geodesy import LocalFrame
from sim.drone.session import FlyOptions, run_session
from sim.render.scene import load_scene
from sim.worlds import demo_scene_dir
from tests.conftest import REPO_ROOT
from tests.exiftool_helpers import exiftool, needs_exiftool
from tests.sim.drone_helpers import short_orbit_csv

UNDULATION_M = 17.5  # N: the photos' heights are above a sea level 17.5 m over the ellipsoid; DUML's home is not
GPX_NS = "{http://www.topografix.com/GPX/1/1}"


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """8 small photos of a short virtual orbit with its DUML capture and Litchi flight log."""
    folder = tmp_path_factory.mktemp("flight")
    run_session(short_orbit_csv(folder / "orbit.csv"), load_scene(demo_scene_dir("small")), folder,
                FlyOptions(photo_size=(64, 48), seed=7, start_utc=dt.datetime(2024, 5, 1, 10, tzinfo=dt.timezone.utc),
                           photo_limit=8, logs=True, progress=False, geoid_undulation_m=UNDULATION_M))
    return folder


def geotag(flight, log: str, out) -> tuple:
    """``aerostereo-ingest geotag`` of the flight's photos from one of its logs, with a GPX: (geotags, sidecar,
    GPX elevations by image name)."""
    assert ingest(["geotag", "--photos", str(flight / "photos"), "--log", str(flight / log),
                   "--out", str(out / "geotags.csv"), "--gpx", str(out / "photos.gpx")]) == 0
    sidecar = json.loads((out / "geotags.json").read_text())
    ele = {point.findtext(f"{GPX_NS}name"): float(point.findtext(f"{GPX_NS}ele"))
           for point in SafeET.parse(out / "photos.gpx").getroot().iter(f"{GPX_NS}trkpt")}
    return load_geotags(out / "geotags.csv"), sidecar, ele


def test_gpx_heights_from_a_duml_home_point_and_from_the_photos_differ_by_their_datums(flight, tmp_path):
    """DUML: the home point's altitude (the virtual drone's take-off ellipsoidal height) + height above take-off;
    Litchi log (no absolute height): the photos' own (above sea level) -> the two differ by N, each GPX point has
    its ele, and the photos' own heights agree with the Litchi one (both barometric above the same take-off)."""
    own = {path.name: read_photo(path).values["absolute_height_m"] for path in (flight / "photos").iterdir()}
    duml, duml_sidecar, duml_ele = geotag(flight, "flight.duml", tmp_path / "duml")
    litchi, litchi_sidecar, litchi_ele = geotag(flight, "flight_log.csv", tmp_path / "litchi")
    assert (duml_sidecar["origin_height_datum"], litchi_sidecar["origin_height_datum"]) == (
        "home_point_altitude", "mean_sea_level")
    assert set(duml_ele) == set(litchi_ele) == set(own) and len(own) == 8
    # per photo, the logs' barometric samples and the photo's own (drawn at its exposure) differ by their noise
    # (DUML: in decimetres); over the photos the datums show
    duml_minus_own = np.array([duml_ele[name] - height for name, height in own.items()])
    litchi_minus_own = np.array([litchi_ele[name] - height for name, height in own.items()])
    assert np.abs(duml_minus_own - UNDULATION_M).max() < 0.3 and np.abs(litchi_minus_own).max() < 0.3
    assert np.median(duml_minus_own) == pytest.approx(UNDULATION_M, abs=0.1)
    assert np.median(litchi_minus_own) == pytest.approx(0.0, abs=0.1)
    assert {p.image_name: p.absolute_height_m for p in duml} == duml_ele
    assert litchi_sidecar["origin"]["h0_ellipsoid_m"] == pytest.approx(
        duml_sidecar["origin"]["h0_ellipsoid_m"] - UNDULATION_M, abs=0.01)  # both the same measured take-off


def readme_exiftool_recipe() -> list[str]:
    """The README's exiftool command ("Use it with..." table) as arguments, and the clock offset it quotes."""
    row = next(line for line in (REPO_ROOT / "README.md").read_text().splitlines() if line.startswith("| exiftool |"))
    command = re.search(r"`[^`]*&& (exiftool -geotag [^`]*)`", row).group(1)
    return shlex.split(command)


def test_the_readme_recipe_quotes_the_clock_offset_of_its_flight_with_its_sign():
    readme = (REPO_ROOT / "README.md").read_text()
    printed = float(re.search(r"aerostereo-ingest geotag --photos flight/photos --log flight/flight\.duml .*\n"
                              r"(?:.*\n)*?clock offset ([-+]\d+\.\d+)", readme).group(1))
    geosync = next(arg for arg in readme_exiftool_recipe() if arg.startswith("-geosync="))
    assert float(geosync.split("=")[1]) == pytest.approx(printed, abs=0.001) and printed < 0


@needs_exiftool
def test_the_readme_exiftool_recipe_lands_every_photo_within_1_mm_with_its_height(flight, tmp_path):
    priors, sidecar, _ = geotag(flight, "flight.duml", tmp_path)
    photos = tmp_path / "photos"
    shutil.copytree(flight / "photos", photos)
    arguments = readme_exiftool_recipe()
    assert arguments[:2] == ["exiftool", "-geotag"] and arguments[-1] == "photos/"
    substitutions = {"photos.gpx": tmp_path / "photos.gpx", "photos/": photos}
    arguments = [f"-geosync={sidecar['clock_offset_s']!r}" if arg.startswith("-geosync=")
                 else substitutions.get(arg, arg) for arg in arguments[1:]]
    exiftool(*arguments, "-overwrite_original")
    rows = exiftool("-n", "-csv", "-GPSLatitude", "-GPSLongitude", "-GPSAltitude", "-GPSAltitudeRef", photos)
    written = {line.split(",")[0].rsplit("/", 1)[-1]: [float(v) for v in line.split(",")[1:]]
               for line in rows.splitlines()[1:]}
    assert len(written) == len(priors) == 8
    for prior in priors:
        lat, lon, altitude, below = written[prior.image_name]
        frame = LocalFrame(prior.lat_deg, prior.lon_deg, 0.0)
        offset_m = np.hypot(*frame.to_enu(lat, lon, 0.0)[:2])
        assert offset_m < 0.001, f"{prior.image_name}: {offset_m * 1000:.2f} mm from its geotag"
        assert below == 0 and altitude == pytest.approx(prior.absolute_height_m, abs=0.001)
