"""tools/bench/bench_refly_recon.py's pure parts: two flights' photos and geotags joined into one folder for recon
(unique names, one ENU frame), and the registration counts on the re-flown arcs."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from capture.geotag_io import load_geotags, read_sidecar
from flightplan.geodesy import LocalFrame
from recon.inputs.priors import read_geotags
from tools.bench.bench_refly_recon import (
    arcs_of_photos, registration, skipped_shot_distances_m, union_geotags, union_photos,
)
from tools.geotag_csv import geotag_row, write_geotags

FIRST = LocalFrame(40.1792, 44.4991, 1000.0)
#: The re-fly's geotag origin: its own take-off fix, 0.5 km north-east and 12 m higher (a frame far enough off that
#: a position left in it would be hundreds of metres wrong; its height is the GPS fix's error, not to be used).
REFLY = LocalFrame(40.1830, 44.5040, 1012.0)
#: A camera 30 m up looking north, 35 deg down (OpenCV camera: x right, y down, z forward), ENU <- camera.
LOOK_NORTH_DOWN = np.array([[1.0, 0.0, 0.0], [0.0, -np.sin(np.radians(35)), np.cos(np.radians(35))],
                            [0.0, -np.cos(np.radians(35)), -np.sin(np.radians(35))]])


def quaternion_wxyz(matrix: np.ndarray) -> tuple[float, float, float, float]:
    x, y, z, w = Rotation.from_matrix(matrix).as_quat()
    return w, x, y, z


@pytest.fixture
def two_flights(tmp_path):
    """Both flights' geotags, each photo named DJI_0001.JPG / DJI_0002.JPG in its own frame; the re-fly's second
    photo untagged."""
    parts = []
    for prefix, frame, east in (("first", FIRST, 10.0), ("refly", REFLY, -20.0)):
        folder = tmp_path / prefix
        folder.mkdir()
        rows = [geotag_row(f"DJI_000{k + 1}.JPG", (east + k, 5.0, 30.0), quaternion_wxyz(LOOK_NORTH_DOWN))
                for k in range(2)]
        parts.append((prefix, write_geotags(folder, rows, origin=frame,
                                            untagged=["DJI_0002.JPG"] if prefix == "refly" else [])))
    return parts


def test_the_union_s_geotags_put_each_flight_s_cameras_at_their_place_in_the_first_flight_s_frame(two_flights,
                                                                                                  tmp_path):
    """Truth by geodesy: each camera's position and a point 100 m along its optical axis, taken to WGS84 from its
    own flight's frame (at the first's origin height: one take-off ground, heights above it kept) and back into the
    first's, are where the union's geotags put them."""
    csv_path = union_geotags(two_flights, tmp_path / "union")
    assert read_sidecar(csv_path)[0] == FIRST
    tags = {tag.image_name: tag for tag in load_geotags(csv_path)}
    assert sorted(tags) == ["first_DJI_0001.JPG", "first_DJI_0002.JPG", "refly_DJI_0001.JPG", "refly_DJI_0002.JPG"]
    for prefix, frame, east in (("first", FIRST, 10.0), ("refly", REFLY, -20.0)):
        for k in range(2):
            camera = np.array([east + k, 5.0, 30.0])
            ahead = camera + 100.0 * LOOK_NORTH_DOWN[:, 2]
            own = LocalFrame(frame.lat0_deg, frame.lon0_deg, FIRST.h0_m)
            expected = FIRST.enu_points(*own.to_geodetic(*np.stack([camera, ahead]).T))
            tag = tags[f"{prefix}_DJI_000{k + 1}.JPG"]
            assert tag.position_enu_m == pytest.approx(expected[0], abs=1e-3)
            axis = tag.R_world_cam[:, 2]
            assert 100.0 * axis == pytest.approx(expected[1] - expected[0], abs=1e-3)
    assert read_geotags(csv_path).untagged == ("refly_DJI_0002.JPG",)


def test_the_union_s_photos_keep_both_cards_photos_of_the_same_name(tmp_path):
    for prefix, payload in (("first", b"one"), ("refly", b"two")):
        (tmp_path / prefix).mkdir()
        (tmp_path / prefix / "DJI_0001.JPG").write_bytes(payload)
    union_photos([("first", tmp_path / "first"), ("refly", tmp_path / "refly")], tmp_path / "union")
    assert sorted(p.name for p in (tmp_path / "union").iterdir()) == ["first_DJI_0001.JPG", "refly_DJI_0001.JPG"]
    assert (tmp_path / "union" / "refly_DJI_0001.JPG").read_bytes() == b"two"


def test_registration_counts_the_union_s_photos_on_the_re_flown_arcs_by_the_check_s_arcs():
    reports = {"first": {"photo_scores": [{"name": "DJI_0001.JPG", "arc": 1}, {"name": "DJI_0002.JPG", "arc": 2},
                                          {"name": "DJI_0003.JPG", "arc": None}]},
               "refly": {"photo_scores": [{"name": "DJI_0001.JPG", "arc": 2}, {"name": "DJI_0002.JPG", "arc": 3}]}}
    arcs = arcs_of_photos(reports)
    assert arcs == {"first_DJI_0001.JPG": 1, "first_DJI_0002.JPG": 2, "first_DJI_0003.JPG": None,
                    "refly_DJI_0001.JPG": 2, "refly_DJI_0002.JPG": 3}
    registered = {"first_DJI_0002.JPG", "refly_DJI_0002.JPG", "first_DJI_0001.JPG"}
    assert registration(arcs, [2], registered) == {"gap_registered": 1, "gap_photos": 2, "refly_registered": 1,
                                                   "refly_photos": 2, "registered": 3, "photos": 5}


def test_a_skipped_shot_s_place_is_measured_to_the_nearest_registered_re_fly_photo(two_flights, tmp_path):
    """The skipped shot was taken 3 m east of the re-fly's first photo (in the re-fly's frame, given in WGS84 as
    truth.json does); the re-fly's second photo is nearer (1 m further east) but not registered, the first flight's
    photos are not the re-fly's: 3 m, to a millimetre. Unregistered, nothing is near it."""
    csv_path = union_geotags(two_flights, tmp_path / "union")
    lat, lon, height = REFLY.to_geodetic(-20.0 + 3.0, 5.0, 30.0)
    truth = {"photos": [{"image_name": "DJI_0007.JPG", "lat_deg": float(lat), "lon_deg": float(lon),
                         "h_ellipsoid_m": float(height)}],
             "faults": [{"kind": "motion_blur", "photos": []}, {"kind": "skipped_shot", "photos": ["DJI_0007.JPG"]}]}
    registered = {"refly_DJI_0001.JPG", "first_DJI_0001.JPG", "first_DJI_0002.JPG"}
    assert skipped_shot_distances_m(truth, csv_path, registered) == [pytest.approx(3.0, abs=1e-3)]
    assert skipped_shot_distances_m(truth, csv_path, {"first_DJI_0001.JPG"}) == [np.inf]
