"""``aerostereo-ingest check``: its parts against analytic cases (shutter events, the orbit's arcs and planned pitch,
the re-fly mission, footprint overlap, the blur measure) and, end to end, virtual flights with known faults."""

from __future__ import annotations

import datetime as dt
import json
import math

import numpy as np
import pytest
from PIL import Image

from capture.check.image_quality import relative_sharpness, sharpness
from capture.check.overlap import neighbour_overlaps
from capture.check.plan import PlannedPath
from capture.check.refly import leg_runs, refly_mission
from capture.check.shutter import check_shutter
from capture.check.verdict import BLUR_RATIO, MIN_ARC_SHARE, PhotoFinding, flag_photo, warnings
from capture.cli import main as ingest_main
from capture.geotag import OWN_GPS_DISAGREES, PHOTO_SOURCE, Geotag
from flightplan import litchi
from flightplan.checks import ERROR, check_mission
from flightplan.demo_location import DEMO_ORIGIN
from flightplan.geodesy import LocalFrame
from flightplan.orbit import OrbitRequest, plan_orbit
from sim.cli import main as render_main
from sim.drone.photo_faults import motion_blur
from tests.conftest import SHARED_DATA
from tests.flightplan.test_litchi_csv import RESEARCH_HEADER
from tests.sim.drone_helpers import short_orbit_csv

#: A nadir camera: OpenCV x right = east, y down = south, z forward = down (columns of R_world_cam).
NADIR = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


@pytest.fixture(scope="module")
def orbit():
    """The default orbit around the demo origin and its path in the frame of its centre at ground level."""
    mission = plan_orbit(OrbitRequest(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg)).mission
    return mission, PlannedPath(mission, LocalFrame(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg, 0.0))


def test_skipped_shots_are_events_without_a_photo_and_gaps_are_missing_shots():
    events = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 8.0, 9.0])  # the camera did not fire at 6 and 7
    photos = np.array([0.0, 1.0, 2.0, 4.0, 5.0, 8.0, 9.0, 10.03])  # none for the event at 3; 10.03: its event lost
    result = check_shutter(events, photos, interval_s=1.0)
    assert result.skipped_s.tolist() == [3.0]
    assert [(gap.start_s, gap.end_s) for gap in result.gaps] == [(5.0, 8.0)]
    assert len(result.shots_s) == 9 and result.longest_gap_s == 3.0
    assert check_shutter(events[:6], events[:6]).interval_s == 1.0  # the median interval without a mission


def test_the_orbit_s_arcs_are_its_photo_legs_and_its_pitch_aims_at_the_centre(orbit):
    mission, plan = orbit
    assert [arc.first_waypoint for arc in plan.arcs] == list(range(len(mission) - 1))
    middles = 0.5 * (plan.enu_m[:-1, :2] + plan.enu_m[1:, :2])
    assert plan.arc_numbers(middles).tolist() == [arc.number for arc in plan.arcs]
    arc = plan.arcs[3]
    assert arc.expected_photos == pytest.approx((arc.end_m - arc.start_m) / (2.5 / 3.6 * 1.0))
    on_circle = np.array([[50.0, 0.0, 30.0], [0.0, -50.0, 30.0]])
    assert plan.planned_pitch_deg(on_circle) == pytest.approx([-math.degrees(math.atan2(30, 50))] * 2, abs=0.01)


def test_the_refly_mission_flies_exactly_the_gap_arcs_and_passes_the_planner_s_checks(orbit):
    mission, _ = orbit
    legs = [7, 2, 3]
    refly = refly_mission(mission, legs)
    assert leg_runs(legs) == [[2, 3], [7]]
    photo_legs = [(refly.waypoints[k].latitude_deg, refly.waypoints[k + 1].latitude_deg)
                  for k in range(len(refly) - 1) if refly.waypoints[k].photo_time_interval_s > 0]
    assert photo_legs == [(mission.waypoints[k].latitude_deg, mission.waypoints[k + 1].latitude_deg)
                          for k in sorted(legs)]
    assert [f for f in check_mission(refly) if f.severity == ERROR] == []
    text = litchi.mission_to_csv_text(refly)
    assert text.splitlines()[0] == RESEARCH_HEADER
    assert litchi.parse_mission_csv(text) == refly


def test_nadir_footprints_overlap_by_the_share_they_have_in_common():
    """Two nadir cameras 30 m up with a 60 m-wide footprint (f = W/2 px): moved 15 m east, the second sees the
    first's footprint east of its 15 m line, three quarters of it (to the grid's 1/16 column)."""
    size, height = (160, 120), 30.0
    focal = np.full(2, size[0] / 2)
    enu = np.array([[0.0, 0.0, height], [15.0, 0.0, height]])
    previous, following = neighbour_overlaps(enu, [NADIR, NADIR], [size, size], focal)
    assert following[0] == pytest.approx(0.75, abs=1 / 16) and previous[1] == pytest.approx(0.75, abs=1 / 16)
    assert math.isnan(previous[0]) and math.isnan(following[1])


def test_blur_drops_the_sharpness_ratio_below_the_limit_and_texture_alone_does_not():
    """Smooth noise at two texture strengths (a forest and a lawn): the gradient-energy ratio is the same for both;
    a 2 px motion blur takes it below BLUR_RATIO of its neighbours'."""
    rng = np.random.default_rng(1)
    textures = [np.clip(128 + strength * rng.standard_normal((120, 160, 3)), 0, 255).astype(np.uint8)
                for strength in (60, 15, 60, 15, 60)]
    grey = [np.asarray(Image.fromarray(t).convert("L"), np.float32) for t in textures]
    ratios = relative_sharpness([sharpness(g) for g in grey])
    assert np.all(ratios > 0.9)
    blurred = np.asarray(Image.fromarray(motion_blur(textures[2], 2.0, (1.0, 0.0))).convert("L"), np.float32)
    ratios = relative_sharpness([sharpness(g) for g in (*grey[:2], blurred, *grey[3:])])
    assert ratios[2] < BLUR_RATIO and np.all(np.delete(ratios, 2) > BLUR_RATIO)


@pytest.mark.parametrize("data_set", ["brighton_beach", "p4m_rtk"])
def test_real_sets_that_register_whole_are_complete_without_a_log(data_set, tmp_path, capsys):
    """Both real sets register every photo in recon (docs/recon.md: 18/18, 32/32): the check, from the photos' own
    EXIF GPS, flags none of them and says what it could not check without a log or a mission."""
    photos = SHARED_DATA / data_set / "images"
    if not photos.is_dir():
        pytest.skip(f"real sample data not found at {SHARED_DATA}")
    assert ingest_main(["check", "--photos", str(photos), "--out", str(tmp_path)]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["verdict"] == "complete" and report["shutter"] is None and report["arcs"] == []
    assert all(not photo["flags"] for photo in report["photo_scores"])
    assert report["photos"]["geotagged"] == len(list(photos.glob("*.JPG")))
    assert any("skipped shots" in item for item in report["not_checked"])


# --- end to end: virtual flights -----------------------------------------------------------------------------------

#: The faulty flight's faults: motion blur on its first arc, a skipped shot on its third (flight seconds).
BLUR_WINDOW, SKIP_WINDOW = "21,24,3", "50,51"


@pytest.fixture(scope="module")
def flights(tmp_path_factory):
    """The three-leg short orbit flown clean and with faults (320x240 photos) over the small world (whose sky bake
    the other flights share), each checked: folder -> (truth, report, exit code)."""
    root = tmp_path_factory.mktemp("check")
    mission = short_orbit_csv(root / "mission.csv", waypoints=4)
    runs = {"clean": [], "faulty": ["--blur", BLUR_WINDOW, "--skip-shots", SKIP_WINDOW]}
    results = {}
    for name, faults in runs.items():
        folder = root / name
        assert render_main(["fly", "--mission", str(mission), "--scene", "demo:small", "--out", str(folder),
                            "--photo-size", "320", "240",
                            "--seed", "0", *faults]) == 0
        code = ingest_main(["check", "--photos", str(folder / "photos"), "--log", str(folder / "flight.duml"),
                            "--mission", str(mission), "--out", str(folder / "check")])
        report = json.loads((folder / "check" / "check.json").read_text())
        results[name] = (json.loads((folder / "truth.json").read_text()), report, code, folder)
    return mission, results


@pytest.mark.slow
def test_a_clean_flight_is_complete(flights):
    _, results = flights
    truth, report, code, folder = results["clean"]
    assert code == 0 and report["verdict"] == "complete" and report["reasons"] == []
    assert report["refly"] is None and not (folder / "check" / "refly.csv").exists()
    assert report["photos"]["geotagged"] == sum(row["taken"] for row in truth["photos"])
    assert (folder / "check" / "check_map.png").stat().st_size > 10_000


@pytest.mark.slow
def test_the_check_names_the_skipped_shot_and_the_blurred_photos(flights):
    _, results = flights
    truth, report, code, _ = results["faulty"]
    assert code == 0 and report["verdict"] == "incomplete"
    by_kind = {fault["kind"]: fault for fault in truth["faults"]}
    skipped, blurred = by_kind["skipped_shot"], by_kind["motion_blur"]
    start = dt.datetime.fromisoformat(truth["start_utc"])
    by_name = {row["image_name"]: row for row in truth["photos"]}
    expected = sorted(start + dt.timedelta(seconds=by_name[name]["t_s"]) for name in skipped["photos"])
    found = sorted(dt.datetime.fromisoformat(t.replace("Z", "+00:00")) for t in report["shutter"]["skipped_shots_utc"])
    assert len(found) == len(expected)
    assert all(abs((f - e).total_seconds()) < 0.2 for f, e in zip(found, expected))
    flagged = {photo["name"] for photo in report["photo_scores"] if "blur" in photo["flags"]}
    truly = set(blurred["photos"])
    precision, recall = len(flagged & truly) / max(len(flagged), 1), len(flagged & truly) / len(truly)
    assert precision >= 0.9 and recall >= 0.9, (flagged, truly)
    assert {kind for photo in report["photo_scores"] for kind in photo["flags"]} == {"blur"}


@pytest.mark.slow
def test_the_refly_csv_covers_exactly_the_gap_arcs_and_passes_the_checks(flights):
    mission_csv, results = flights
    truth, report, _, folder = results["faulty"]
    mission = litchi.read_mission_csv(mission_csv)
    plan = PlannedPath(mission, LocalFrame.from_dict(truth["origin"]))
    by_name = {row["image_name"]: row for row in truth["photos"]}
    faulted = [by_name[name] for fault in truth["faults"] for name in fault["photos"]]
    gap_arcs = set(plan.arc_numbers(np.array([[row["east_m"], row["north_m"]] for row in faulted])).tolist())
    assert set(report["refly"]["arcs"]) == gap_arcs and len(gap_arcs) < len(plan.arcs)
    refly = litchi.read_mission_csv(folder / "check" / "refly.csv")
    assert (folder / "check" / "refly.csv").read_text().splitlines()[0] == RESEARCH_HEADER
    assert [f for f in check_mission(refly) if f.severity == ERROR] == []
    legs = {(row.latitude_deg, row.longitude_deg) for row in refly.waypoints[:-1]
            if row.photo_time_interval_s > 0}
    assert legs == {(mission.waypoints[arc.first_waypoint].latitude_deg,
                     mission.waypoints[arc.first_waypoint].longitude_deg) for arc in plan.arcs
                    if arc.number in gap_arcs}


@pytest.mark.slow
def test_without_a_log_the_blur_is_still_named_and_the_skipped_shot_is_said_unchecked(flights, capsys):
    mission_csv, results = flights
    truth, _, _, folder = results["faulty"]
    assert ingest_main(["check", "--photos", str(folder / "photos"), "--mission", str(mission_csv),
                        "--out", str(folder / "check_without_log")]) == 0
    report = json.loads(capsys.readouterr().out)
    blurred = {name for fault in truth["faults"] if fault["kind"] == "motion_blur" for name in fault["photos"]}
    assert {photo["name"] for photo in report["photo_scores"] if photo["flags"]} == blurred
    assert report["shutter"] is None and any("skipped shots" in item for item in report["not_checked"])


@pytest.mark.parametrize("reason, flagged", [
    (f"{OWN_GPS_DISAGREES} 14.2 m horizontally and 0.3 m in height from the logs' position at its time", True),
    ("in a telemetry gap of 3.10 s (limit 2 s)", False), (None, False)])
def test_gps_is_flagged_where_the_photo_s_own_gps_disagreed_with_the_logs_not_in_a_dropout(reason, flagged):
    tag = Geotag("DJI_0001.JPG", 0.0, "event", PHOTO_SOURCE if reason else "duml/event", 40.0, 44.0, 30.0, 1030.0,
                 np.zeros(3), np.array([0.0, -31.0, 0.0]), np.array([0.0, 0.0, 30.0]), None)
    finding = PhotoFinding(tag, 1, 1.0, 0.0, 0.0, 0.0, -31.0, 0.9, reason, 2.0)
    flag_photo(finding)
    assert ("gps" in finding.flags) == flagged and len(finding.flags) == int(flagged)
    assert (finding.score < 1.0) == flagged
    assert bool(warnings([finding])) == (reason is not None and not flagged)  # a dropout: said, not flagged


@pytest.mark.parametrize("off_path_m, flagged", [(3.0, False), (8.9, False), (9.5, True), (float("nan"), False)])
def test_a_photo_off_the_planned_path_beyond_gps_error_is_flagged(off_path_m, flagged):
    tag = Geotag("DJI_0001.JPG", 0.0, "event", "duml/event", 40.0, 44.0, 30.0, 1030.0, np.zeros(3),
                 np.array([0.0, -31.0, 0.0]), np.array([0.0, 0.0, 30.0]), None)
    finding = PhotoFinding(tag, 1, 1.0, 0.0, 0.0, 0.0, -31.0, 0.9, None, off_path_m)
    flag_photo(finding)
    assert list(finding.flags) == (["path"] if flagged else [])


@pytest.mark.slow
def test_the_refly_csv_flown_by_the_virtual_drone_fills_the_gap_arcs(flights, capsys):
    """Stretch of issue 41, without the recon: the re-fly CSV flown from the original take-off gives each arc it
    re-flies at least MIN_ARC_SHARE of its planned photos, placed by their geotags on the original mission's arcs;
    the arcs it skips get at most the odd photo of a neighbouring arc's ends (its curves)."""
    mission_csv, results = flights
    truth, report, _, folder = results["faulty"]
    origin = truth["origin"]
    refly = folder / "refly_flight"
    assert render_main(["fly", "--mission", str(folder / "check" / "refly.csv"), "--scene", "demo:small",
                        "--out", str(refly), "--photo-size", "160", "120", "--seed", "1",
                        "--home", str(origin["lat0_deg"]), str(origin["lon0_deg"])]) == 0
    capsys.readouterr()
    assert ingest_main(["check", "--photos", str(refly / "photos"), "--log", str(refly / "flight.duml"),
                        "--mission", str(mission_csv), "--out", str(refly / "check")]) == 0
    arcs = {arc["arc"]: arc for arc in json.loads(capsys.readouterr().out)["arcs"]}
    for number, arc in arcs.items():
        if number in report["refly"]["arcs"]:
            assert arc["photos"] >= MIN_ARC_SHARE * arc["expected_photos"], arc
        else:
            assert arc["photos"] <= 0.25 * arc["expected_photos"], arc
