"""``aerostereo-ingest check`` on hostile input: an empty card, a log of another flight, photos from another day, a
mission that is not Litchi's or not of the photos' place, outputs that name an input.

Each case must end with exit 2, one stderr line naming what was wrong, no traceback and no file left behind
(:mod:`tests.bad_input.harness`). Each fails on the code before the check (run against it: 12 of 12): argparse's
"invalid choice: 'check'" names neither the input nor what was wrong with it.
"""

from __future__ import annotations

import shutil
from dataclasses import replace

import pytest

from flightplan import litchi
from flightplan.orbit import OrbitRequest, plan_orbit
from tests.bad_input.harness import Case, assert_refused, run_case
from tests.bad_input.test_ingest_geotag import MINNESOTA_PHOTOS, flight
from tests.capture.test_geotag_checks import yerevan_log

CHECK = ["check", "--photos", "{tmp}/photos", "--log", "{tmp}/flight.csv", "--out", "{tmp}/check"]


def empty_card(tmp):
    """The synthetic flight's log and an empty photo folder (a card formatted, or the wrong folder)."""
    flight(tmp)
    shutil.rmtree(tmp / "photos")
    (tmp / "photos").mkdir()


def photos_and_the_log_of_another_flight(tmp):
    """The synthetic flight's log and photos taken at the same times 1 km north (their own GPS says so): the log
    of another flight."""
    flight(tmp, north_shift_m=1000.0)


def minnesota_photos(tmp):
    """Real photos of another place and day (brighton_beach, 2017) with the synthetic Yerevan log."""
    if not MINNESOTA_PHOTOS.is_dir():
        pytest.skip("real sample data not found (set AEROSTEREO_SHARED_DATA)")
    flight(tmp)
    shutil.rmtree(tmp / "photos")
    shutil.copytree(MINNESOTA_PHOTOS, tmp / "photos")


def mission_text(tmp, text: str):
    """The synthetic flight and ``mission.csv`` holding ``text``."""
    flight(tmp)
    (tmp / "mission.csv").write_text(text)


def mission_without_timed_photos(tmp):
    """The synthetic flight and the default orbit with its photo interval removed (a mission the photos were not
    taken on)."""
    flight(tmp)
    plan = plan_orbit(OrbitRequest(40.1792, 44.4991))
    rows = tuple(replace(row, photo_time_interval_s=litchi.DISABLED_INTERVAL) for row in plan.mission.waypoints)
    litchi.write_mission_csv(litchi.Mission(rows), tmp / "mission.csv")


def mission_elsewhere(tmp):
    """The synthetic flight and the default orbit planned 2 km north of its centre (a Litchi CSV of another place)."""
    flight(tmp)
    plan = plan_orbit(OrbitRequest(40.1792 + 0.018, 44.4991))
    litchi.write_mission_csv(plan.mission, tmp / "mission.csv")


CASES = [
    Case("check-empty-card", "aerostereo-ingest", CHECK, r"photos: no readable JPEG photos", empty_card),
    Case("check-log-of-another-flight", "aerostereo-ingest", CHECK,
         r"photos' own GPS is a median 98\d m .*more than the 9 m \(--max-misfit\)", photos_and_the_log_of_another_flight),
    Case("check-photos-from-another-day", "aerostereo-ingest", CHECK, r"at least 24 h apart .*\+-14\.5 h",
         lambda tmp: flight(tmp, camera_shift_s=86400.0)),
    Case("check-photos-of-another-place-and-year", "aerostereo-ingest", CHECK, r"7\.8\d years apart",
         minnesota_photos),
    Case("check-mission-not-litchi", "aerostereo-ingest", [*CHECK, "--mission", "{tmp}/mission.csv"],
         r"mission\.csv", lambda tmp: mission_text(tmp, "name,lat,lon\nA,40.1,44.5\n")),
    Case("check-mission-empty", "aerostereo-ingest", [*CHECK, "--mission", "{tmp}/mission.csv"],
         r"mission\.csv", lambda tmp: mission_text(tmp, "")),
    Case("check-mission-without-timed-photos", "aerostereo-ingest", [*CHECK, "--mission", "{tmp}/mission.csv"],
         r"--mission .*mission\.csv: no leg takes timed photos", mission_without_timed_photos),
    Case("check-mission-is-the-out-s-refly", "aerostereo-ingest",
         [*CHECK[:-1], "{tmp}", "--mission", "{tmp}/refly.csv"], r"refly\.csv: is also --mission",
         lambda tmp: mission_text(tmp, "x\n") or (tmp / "mission.csv").rename(tmp / "refly.csv")),
    Case("check-mission-of-another-place", "aerostereo-ingest", [*CHECK, "--mission", "{tmp}/mission.csv"],
         r"--mission .*mission\.csv: the photos lie a median 19\d\d m from its path", mission_elsewhere),
    Case("check-no-photos-folder", "aerostereo-ingest", CHECK, r"--photos .*photos: .*expected the card's folder",
         lambda tmp: yerevan_log(tmp / "flight.csv", duration_s=30.0)),
    Case("check-log-missing", "aerostereo-ingest",
         ["check", "--photos", "{tmp}/photos", "--log", "{tmp}/nothing.duml", "--out", "{tmp}/check"],
         r"--log .*nothing\.duml", flight),
    Case("check-out-is-a-file", "aerostereo-ingest",
         ["check", "--photos", "{tmp}/photos", "--log", "{tmp}/flight.csv", "--out", "{tmp}/flight.csv"],
         r"--out .*flight\.csv: is a file; expected a folder", flight),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    assert_refused(run_case(case, tmp_path), case, tmp_path)
