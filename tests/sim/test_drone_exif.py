"""The virtual drone's photos carry the EXIF tag set a real DJI camera writes, each tag with the TIFF type DJI gives
it, read back by exifread (a reader independent of our writer, capture.exif_tiff) and validated by exiftool; their
heights above sea level follow the stated geoid undulation. (XMP escaping: tests/capture/test_geotag.py; our own
reader on these photos: tests/sim/test_drone_link.py.)"""

import datetime as dt
from fractions import Fraction

import exifread
import numpy as np
import pytest

from capture.geotag import Geotag
from capture.logs.photos import read_photo
from sim.drone import Imperfections
from sim.drone.exif import NOT_WRITTEN
from sim.drone.photos import photo_camera, render_photos, write_dji_jpeg
from sim.drone.session import FlyOptions, fly_litchi_mission
from sim.render.scene import load_scene
from sim.worlds import demo_scene_dir
from tests.exiftool_helpers import exiftool, needs_exiftool, serious_warnings
from tests.sim.drone_helpers import short_orbit_csv

CAMERA_TIME = dt.datetime(2024, 5, 1, 10, 1, 2, 345000)
REAL_DJI_FOLDERS = ("p4m_rtk/images", "brighton_beach/images")


#: TIFF type codes (TIFF 6.0) that the checks below name.
UNDEFINED, SRATIONAL = 7, 10


def exif_tags(path) -> dict:
    with open(path, "rb") as handle:
        return exifread.process_file(handle, details=False)


def tag_types(path) -> dict[str, int]:
    """exifread name -> TIFF type code of each tag in IFD0 (``Image``), the Exif, GPS and Interop IFDs."""
    return {name: tag.field_type for name, tag in exif_tags(path).items()
            if name.split()[0] in ("Image", "EXIF", "GPS", "Interoperability")}


def ratio(tag) -> float:
    return float(Fraction(tag.values[0].num, tag.values[0].den))


def a_geotag(**changes) -> Geotag:
    values = dict(image_name="DJI_0001.JPG", time_s=0.0, time_source="camera", source="drone", lat_deg=40.1792,
                  lon_deg=44.4991, height_above_takeoff_m=30.25, absolute_height_m=1012.5,
                  aircraft_ypr_deg=np.array([10.0, -2.0, 1.0]), gimbal_ypr_deg=np.array([10.0, -30.0, 0.0]),
                  enu_m=np.full(3, np.nan), R_world_cam=None)
    return Geotag(**(values | changes))


@pytest.fixture(scope="module")
def real_dji_tag_sets(shared_data) -> list[set[str]]:
    """The exifread tag names of every real DJI photo in the sample data (two camera models)."""
    paths = sorted(p for folder in REAL_DJI_FOLDERS for p in (shared_data / folder).glob("*.JPG"))
    assert len(paths) > 40
    return [set(exif_tags(path)) for path in paths]


@pytest.fixture(scope="module")
def real_dji_tag_types(shared_data) -> list[dict[str, int]]:
    """The TIFF type code of every IFD0/Exif/GPS/Interop tag of one real photo of each DJI camera model."""
    photos = [shared_data / "brighton_beach/images/DJI_0018.JPG", shared_data / "p4m_rtk/images/DJI_0010.JPG"]
    return [tag_types(path) for path in photos]


@pytest.fixture()
def virtual_photo(tmp_path):
    path = tmp_path / "DJI_0001.JPG"
    rgb = np.random.default_rng(0).integers(0, 255, (30, 40, 3), dtype=np.uint8)
    write_dji_jpeg(path, rgb, a_geotag(), CAMERA_TIME, photo_camera(40, 30))
    return path


def test_virtual_photo_has_every_tag_all_real_dji_photos_have(real_dji_tag_sets, virtual_photo):
    every_dji_photo = set.intersection(*real_dji_tag_sets)
    expected = every_dji_photo - set(NOT_WRITTEN)
    missing = expected - set(exif_tags(virtual_photo))
    assert not missing, f"DJI tags missing from the virtual photo: {sorted(missing)}"
    # the omissions are real DJI tags (no stale names), and the expected set is the substantial one DJI writes
    assert set(NOT_WRITTEN) <= set.union(*real_dji_tag_sets)
    assert {"EXIF ExifVersion", "EXIF FlashPixVersion", "EXIF ExifImageWidth", "EXIF ColorSpace",
            "EXIF ComponentsConfiguration", "GPS GPSVersionID", "GPS GPSAltitudeRef", "Image Software"} <= expected


def test_virtual_photo_tags_have_the_tiff_types_of_real_dji_photos(real_dji_tag_types, virtual_photo):
    """A reader decodes a tag by its TIFF type: ComponentsConfiguration and FileSource are UNDEFINED (not BYTE),
    ExposureBiasValue SRATIONAL (an unsigned RATIONAL would read a negative compensation as a huge one)."""
    ours = tag_types(virtual_photo)
    for real in real_dji_tag_types:
        shared = set(ours) & set(real)
        assert len(shared) > 40
        assert {name: ours[name] for name in shared} == {name: real[name] for name in shared}
    assert (ours["EXIF ComponentsConfiguration"], ours["EXIF FileSource"]) == (UNDEFINED, UNDEFINED)
    assert ours["EXIF ExposureBiasValue"] == SRATIONAL
    assert exif_tags(virtual_photo)["EXIF FileSource"].values == [3]  # digital still camera, as DJI writes it


@needs_exiftool
def test_exiftool_validates_a_virtual_photo_without_a_serious_warning(virtual_photo):
    assert serious_warnings(virtual_photo) == []
    assert exiftool("-s3", "-FileSource", "-ComponentsConfiguration", virtual_photo).splitlines() == [
        "Digital Camera", "Y, Cb, Cr, -"]


def test_virtual_photo_tag_values(virtual_photo):
    tags = exif_tags(virtual_photo)
    text = {name: str(tag) for name, tag in tags.items()}
    assert (text["Image Make"], text["Image Model"]) == ("DJI", "FC7103")
    assert (text["EXIF ExifVersion"], text["EXIF FlashPixVersion"], text["EXIF ColorSpace"]) == ("0230", "0100", "sRGB")
    assert (tags["EXIF ExifImageWidth"].values[0], tags["EXIF ExifImageLength"].values[0]) == (40, 30)
    assert text["EXIF DateTimeOriginal"] == text["EXIF DateTimeDigitized"] == "2024:05:01 10:01:02"
    for name in ("EXIF SubSecTime", "EXIF SubSecTimeOriginal", "EXIF SubSecTimeDigitized"):
        assert text[name] == "345"
    assert text["GPS GPSAltitudeRef"] == "0" and ratio(tags["GPS GPSAltitude"]) == pytest.approx(1012.5)
    assert tags["GPS GPSVersionID"].values == [2, 3, 0, 0]


def test_photo_below_sea_level_says_so(tmp_path):
    path = tmp_path / "DJI_0002.JPG"
    write_dji_jpeg(path, np.zeros((30, 40, 3), np.uint8), a_geotag(absolute_height_m=-12.0), CAMERA_TIME,
                   photo_camera(40, 30))
    tags = exif_tags(path)
    assert str(tags["GPS GPSAltitudeRef"]) == "1" and ratio(tags["GPS GPSAltitude"]) == pytest.approx(12.0)
    assert read_photo(path).values["absolute_height_m"] == pytest.approx(-12.0)


def test_heights_above_sea_level_follow_the_stated_geoid_undulation(tmp_path):
    """EXIF GPSAltitude and XMP AbsoluteAltitude = ellipsoidal height - N; RelativeAltitude stays above take-off."""
    world = load_scene(demo_scene_dir("small"))
    mission = fly_litchi_mission(short_orbit_csv(tmp_path / "orbit.csv", waypoints=8, photo_interval_s=20.0), world,
                                 seed=3, imperfections=Imperfections.none())
    undulation = 17.5
    render_photos(mission, world, tmp_path / "photos", photo_camera(32, 24, lens=0.0), CAMERA_TIME, limit=1,
                  progress=False, geoid_undulation_m=undulation)
    index = int(np.flatnonzero(mission.photos.taken)[0])
    relative = mission.photos.measured_height_above_takeoff_m[index]
    expected = mission.sensors.measured_home()[2] - undulation + relative
    path = tmp_path / "photos" / mission.photos.names[index]
    assert ratio(exif_tags(path)["GPS GPSAltitude"]) == pytest.approx(expected, abs=1e-5)  # written to 0.01 mm
    values = read_photo(path).values
    assert values["absolute_height_m"] == pytest.approx(expected, abs=1e-6)
    assert values["height_above_takeoff_m"] == pytest.approx(relative, abs=1e-6)
    assert mission.photos.height_ellipsoid_m[index] - undulation == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize("undulation", [-150.0, 0.0, 86.0, 150.0])
def test_every_geoid_undulation_on_earth_is_accepted(undulation):
    """Earth's geoid lies -107..+86 m from the ellipsoid (EGM2008): the whole +-150 m range is a flight's to state."""
    assert FlyOptions(geoid_undulation_m=undulation).geoid_undulation_m == undulation


@pytest.mark.parametrize("undulation", [150.5, -1e308, float("inf"), float("nan")])
def test_a_geoid_undulation_no_place_has_is_refused(undulation):
    """1e308 used to give every photo a NaN GPSAltitude; beyond +-150 m no height above sea level is one on Earth."""
    with pytest.raises(ValueError, match=r"geoid undulation must be a finite number of metres within \+-150"):
        FlyOptions(geoid_undulation_m=undulation)
