"""Litchi CSV: the exact header, exact round trips, the imperial variant and clear errors."""

import dataclasses

import pytest

from flightplan import litchi
from flightplan.orbit import OrbitRequest, plan_orbit

# Copied from research/litchi.md section 1.1 (a real Mission Hub export's header).
RESEARCH_HEADER = (
    "latitude,longitude,altitude(m),heading(deg),curvesize(m),rotationdir,gimbalmode,gimbalpitchangle,"
    "actiontype1,actionparam1,actiontype2,actionparam2,actiontype3,actionparam3,actiontype4,actionparam4,"
    "actiontype5,actionparam5,actiontype6,actionparam6,actiontype7,actionparam7,actiontype8,actionparam8,"
    "actiontype9,actionparam9,actiontype10,actionparam10,actiontype11,actionparam11,actiontype12,"
    "actionparam12,actiontype13,actionparam13,actiontype14,actionparam14,actiontype15,actionparam15,"
    "altitudemode,speed(m/s),poi_latitude,poi_longitude,poi_altitude(m),poi_altitudemode,"
    "photo_timeinterval,photo_distinterval"
)


@pytest.fixture(scope="module")
def mission():
    return plan_orbit(OrbitRequest(-33.9, -179.9999, start_bearing_deg=12.345)).mission


def test_header_is_the_exact_46_columns():
    assert ",".join(litchi.HEADER) == RESEARCH_HEADER
    assert len(litchi.HEADER) == 46


def test_round_trip_is_exact(tmp_path, mission):
    path = litchi.write_mission_csv(mission, tmp_path / "sub" / "m.csv")
    raw = path.read_bytes()
    assert b"\r" not in raw and b'"' not in raw and raw.endswith(b"\n")
    lines = raw.decode().splitlines()
    assert lines[0] == RESEARCH_HEADER
    assert all(len(line.split(",")) == 46 for line in lines)
    back = litchi.read_mission_csv(path)
    assert back == mission  # every field, bit for bit
    for a, b in zip(back.waypoints, mission.waypoints):
        assert abs(a.latitude_deg - b.latitude_deg) < 1e-9 and abs(a.longitude_deg - b.longitude_deg) < 1e-9
    assert [p.name for p in path.parent.iterdir()] == ["m.csv"]  # no temporary file left behind


def test_numbers_are_positional_with_a_dot():
    assert litchi.format_number(1e-8) == "0.00000001"
    assert litchi.format_number(-1) == "-1"
    assert litchi.format_number(0.1 + 0.2) == "0.30000000000000004"
    with pytest.raises(ValueError):
        litchi.format_number(float("nan"))


def test_actions_round_trip():
    waypoint = litchi.Waypoint(1.5, 2.5, actions=((litchi.ACTION_STAY_MS, 2000.0), (litchi.ACTION_TAKE_PHOTO, 0.0)))
    text = litchi.mission_to_csv_text(litchi.Mission((waypoint,)))
    assert litchi.parse_mission_csv(text) == litchi.Mission((waypoint,))


def test_imperial_variant_is_converted_to_metres():
    header = RESEARCH_HEADER.replace("(m)", "(ft)").replace("speed(ft/s)", "speed(m/s)")
    waypoint = litchi.Waypoint(47.0, 8.0, 100.0, curve_size_m=10.0, poi_altitude_m=3.0)
    metric = litchi.mission_to_csv_text(litchi.Mission((waypoint,)))
    row = metric.splitlines()[1]
    waypoint = litchi.parse_mission_csv(header + "\n" + row + "\n").waypoints[0]
    assert waypoint.altitude_m == pytest.approx(30.48)
    assert waypoint.curve_size_m == pytest.approx(3.048)
    assert waypoint.poi_altitude_m == pytest.approx(0.9144)
    assert waypoint.latitude_deg == 47.0


def test_unknown_columns_are_ignored_and_missing_ones_get_defaults():
    text = "Longitude,extra,latitude,speed(m/s)\n8.5,hello,47.25,3\n"
    waypoint = litchi.parse_mission_csv(text).waypoints[0]
    assert (waypoint.latitude_deg, waypoint.longitude_deg, waypoint.speed_m_s) == (47.25, 8.5, 3.0)
    assert waypoint.photo_time_interval_s == litchi.DISABLED_INTERVAL and waypoint.actions == ()


@pytest.mark.parametrize(
    "text, where, what",
    [
        ("latitude,altitude(m)\n1,2\n", "m.csv:1", "longitude"),
        ("latitude,longitude\n1,2\n,3\n", "m.csv:3", "'latitude' is empty"),
        ("latitude,longitude\n1,2\n1,east\n", "m.csv:3", "expected a number"),
        ("latitude,longitude\n1,2,3\n", "m.csv:2", "expected 2 comma-separated fields"),
        ("", "m.csv:1", "empty file"),
        ("latitude,longitude,gimbalmode\n1,2,1.5\n", "m.csv:2", "integer code"),
    ],
)
def test_bad_files_name_file_and_line(tmp_path, text, where, what):
    path = tmp_path / "m.csv"
    path.write_text(text)
    with pytest.raises(litchi.LitchiFormatError) as caught:
        litchi.read_mission_csv(path)
    assert f"{path.parent}/{where}" in str(caught.value) and what in str(caught.value)


def test_binary_file_names_the_byte(tmp_path):
    path = tmp_path / "m.csv"
    path.write_bytes(b"latitude,longitude\n1,2\n\xff\xfe\n")
    with pytest.raises(litchi.LitchiFormatError, match=r"m.csv:3: byte offset 23 is not UTF-8"):
        litchi.read_mission_csv(path)


def test_mission_column_view(mission):
    altitudes = mission.column("altitude_m")
    assert altitudes.shape == (len(mission),) and set(altitudes) == {30.0}
    assert dataclasses.is_dataclass(mission.waypoints[0])


def test_a_file_with_more_rows_than_litchi_allows_is_not_a_mission(tmp_path, mission):
    rows = litchi.mission_to_csv_text(litchi.Mission(mission.waypoints[:1] * litchi.MAX_WAYPOINTS)).splitlines()
    path = tmp_path / "m.csv"
    path.write_text("\n".join(rows) + "\n")
    assert len(litchi.read_mission_csv(path).waypoints) == litchi.MAX_WAYPOINTS
    path.write_text("\n".join(rows + rows[-1:]) + "\n")
    with pytest.raises(litchi.LitchiFormatError, match=rf"m.csv:{litchi.MAX_WAYPOINTS + 2}: more than 99 waypoints"):
        litchi.read_mission_csv(path)


def test_a_file_larger_than_any_mission_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "m.csv"
    path.write_bytes(b"latitude,longitude\n" + b"1,2\n" * (litchi.MAX_MISSION_FILE_BYTES // 4))
    with pytest.raises(litchi.LitchiFormatError, match="m.csv: larger than 1024 KiB"):
        litchi.read_mission_csv(path)
