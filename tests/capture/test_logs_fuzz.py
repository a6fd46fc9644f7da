"""Readers on mutated lines: never a crash, always a clear error or a reject naming file and line."""

import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from capture.logs import read_track
from capture.logs.photos import parse_dji_xmp
from capture.track import LogFormatError

SAMPLES = ["dji/DJI_SRT_Parser__p4_rtk.SRT", "dji/DJI_SRT_Parser__matrice_300.srt",
           "dji/DJI_SRT_Parser__air2s.srt", "litchi/airdata_mini2_imperial_head.csv"]
GARBAGE = st.text(alphabet=st.sampled_from(list("0123456789-.,:()[]° nMmGPSHabc\t\"") + ["\x00", "é"]), max_size=60)


@st.composite
def mutation(draw, line_count):
    line = draw(st.integers(0, line_count - 1))
    kind = draw(st.sampled_from(["replace", "truncate", "insert", "delete", "splice"]))
    return line, kind, draw(GARBAGE), draw(st.integers(0, 80))


def mutate(lines, line, kind, text, cut):
    lines = list(lines)
    if kind == "replace":
        lines[line] = text
    elif kind == "truncate":
        lines[line] = lines[line][:cut]
    elif kind == "insert":
        lines.insert(line, text)
    elif kind == "delete":
        del lines[line]
    else:
        lines[line] = lines[line][:cut] + text + lines[line][cut:]
    return lines


def names_a_place(message: str, path: Path) -> bool:
    return str(path) in message


@pytest.mark.parametrize("sample", SAMPLES)
def test_mutated_logs_fail_clearly(shared_data, tmp_path, sample):
    original = (shared_data / sample).read_text(encoding="utf-8").splitlines()
    target = tmp_path / Path(sample).name

    @settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(mutation(len(original)))
    def check(change):
        target.write_text("\n".join(mutate(original, *change)) + "\n", encoding="utf-8")
        try:
            track = read_track(target, start_time_s=0.0)
        except LogFormatError as error:
            assert names_a_place(str(error), target), str(error)
            return
        report = track.report
        assert report.rows_used + len(report.rejected) == report.rows_read  # nothing skipped silently
        for problem in report.rejected:
            assert problem.file == str(target) and (problem.line is None or problem.line >= 1)
            assert re.match(rf"{re.escape(str(target))}:\d+: ", str(problem)) or problem.line is None
        assert len(track) == report.rows_used

    check()


def test_reject_names_file_and_line(shared_data, tmp_path):
    lines = (shared_data / "litchi" / "airdata_mini2_imperial_head.csv").read_text().splitlines()
    lines[3] = lines[3].replace("47.5726975411239", "47.57x")  # data row 3 is file line 4
    lines[5] = lines[5][:40]
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(lines) + "\n")
    track = read_track(path)
    assert [p.line for p in track.report.rejected] == [4, 6]
    assert "expected a number, got '47.57x'" in str(track.report.rejected[0])
    assert str(track.report.rejected[1]).startswith(f"{path}:6: truncated row")
    assert len(track) == 48 and track.report.rows_read == 50


def test_no_fix_rows_are_rejected_not_used(shared_data, tmp_path):
    lines = (shared_data / "litchi" / "airdata_mini2_imperial_head.csv").read_text().splitlines()
    cells = lines[1].split(",")
    cells[2], cells[3] = "0", "0"
    lines[1] = ",".join(cells)
    path = tmp_path / "nofix.csv"
    path.write_text("\n".join(lines) + "\n")
    track = read_track(path)
    assert len(track) == 49 and track.report.rejected[0].line == 2
    assert "no GPS fix" in track.report.rejected[0].reason and track["lat_deg"].min() > 47


def test_out_of_range_positions_are_rejected_with_one_reason(shared_data, tmp_path):
    lines = (shared_data / "litchi" / "airdata_mini2_imperial_head.csv").read_text().splitlines()
    cells = lines[1].split(",")
    cells[2] = "147.5"  # latitude
    lines[1] = ",".join(cells)
    path = tmp_path / "bad_lat.csv"
    path.write_text("\n".join(lines) + "\n")
    track = read_track(path)
    assert len(track) == 49 and track.report.reasons() == {"position out of range": 1}
    assert "latitude must be within [-90, 90] degrees, got 147.5" in str(track.report.rejected[0])


def test_unknown_unit_is_a_clear_error(shared_data, tmp_path):
    text = (shared_data / "litchi" / "airdata_mini2_imperial_head.csv").read_text()
    path = tmp_path / "furlong.csv"
    path.write_text(text.replace("height_above_takeoff(feet)", "height_above_takeoff(furlongs)", 1))
    with pytest.raises(LogFormatError, match=r"furlong.csv:1: column 5 'height_above_takeoff\(furlongs\)': unknown unit"):
        read_track(path)


@settings(max_examples=150, deadline=None)
@given(st.text(max_size=200))
def test_xmp_parser_never_crashes(text):
    try:
        values = parse_dji_xmp("<x:xmpmeta xmlns:x='adobe:ns:meta/'>" + text + "</x:xmpmeta>")
    except ValueError:
        return
    assert isinstance(values, dict)


LITCHI_HEADER = (  # the 92-column header of a real Litchi iOS 2.1.1 export (research/litchi.md §3.1)
    "latitude,longitude,altitude(feet),ascent(feet),speed(mph),distance(feet),max_altitude(feet),max_ascent(feet),"
    "max_speed(mph),max_distance(feet),time(millisecond),datetime(utc),datetime(local),satellites,pressure(Pa),"
    "temperature(F),voltage(v),home_latitude,home_longitude,velocityX(mph),velocityY(mph),velocityZ(mph),pitch(deg),"
    "roll(deg),yaw(deg),powerlevel,isflying,istakingphoto,remainPowerPercent,remainLifePercent,currentCurrent,"
    "currentElectricity,currentVoltage,batteryTemperature,dischargeCount,flightmode,isMotorsOn,isTakingVideo,"
    "Rc_elevator,Rc_aileron,Rc_throttle,Rc_rudder,Rc_gyro,timestamp,Battery_Cell1,Battery_Cell2,Battery_Cell3,"
    "Battery_Cell4,Battery_Cell5,Battery_Cell6,Dronetype,AppVersion,Planename,FlyControllerSerialNumber,"
    "RemoteSerialNumber,BatterySerialNumber,CENTER_BATTERY.productDate,CENTER_BATTERY.serialNo,"
    "CENTER_BATTERY.fullCapacity,CENTER_BATTERY.productDateRaw,pitchRaw,rollRaw,yawRaw,gimbalPitchRaw,gimbalRollRaw,"
    "gimbalYawRaw,flyState,altitudeRaw,speedRaw,distanceRaw,velocityXRaw,velocityYRaw,velocityZRaw,data_reuse,"
    "App_Tip,App_Warning,downlinkSignalQuality,uplinkSignalQuality,transmissionChannel,rcModeSwitch,rcHome,rcPause,"
    "rcTransform,rcJoystickMode,appMode,FlyControllerSerialNumber_legacy,RemoteSerialNumber_legacy,"
    "BatterySerialNumber_legacy,Battery2SerialNumber,frontAvoidDist,backAvoidDist,isBrakingToAvoid"
)


def test_litchi_imperial_export(tmp_path):
    names = LITCHI_HEADER.split(",")
    assert len(names) == 92
    rows = []
    for k, (photo, stamp) in enumerate([(0, "21:15:26.199"), (1, "21:15:26.312"), (1, "21:15:26.396"),
                                        (0, "21:15:26.487"), (1, "21:15:26.601")]):
        row = dict.fromkeys(names, "0")
        row.update({"latitude": f"{54.1 + k * 1e-5:.6f}", "longitude": "18.5", "altitude(feet)": "19",
                    "speed(mph)": "6.93", "time(millisecond)": str(k * 100), "datetime(utc)": f"2018-02-16 {stamp}",
                    "datetime(local)": f"2018-02-16 12:{stamp[3:]}", "yaw(deg)": "-148", "pitch(deg)": "-3",
                    "istakingphoto": str(photo), "gimbalPitchRaw": "-900", "gimbalYawRaw": "322",
                    "home_latitude": "54.1", "home_longitude": "18.5", "AppVersion": "(null)", "flightmode": "WP"})
        rows.append(",".join(row[n] for n in names))
    path = tmp_path / "2018-02-16_12-15-26_v2_Mavic_Litchi.csv"
    path.write_text(LITCHI_HEADER + "\n" + "\n".join(rows) + "\n")
    track = read_track(path)
    assert track.report.kind == "litchi" and track.report.rejected == [] and len(track) == 5
    assert track["height_above_takeoff_m"][0] == pytest.approx(19 * 0.3048)
    assert track["speed_m_s"][0] == pytest.approx(6.93 * 0.44704)
    assert track["gimbal_pitch_deg"][0] == pytest.approx(-90.0) and track["gimbal_yaw_deg"][0] == pytest.approx(32.2)
    assert track["aircraft_yaw_deg"][0] == pytest.approx(-148.0)
    assert track.home.lat_deg == pytest.approx(54.1)
    path.write_text(path.read_text().replace(",54.1,18.5,", ",94.1,18.5,"))  # a home latitude out of range
    assert read_track(path).home is None
    # datetime(utc) already has milliseconds: used as is; rising edges placed between the 0 row and the 1 row
    assert track.time_s[1] - track.time_s[0] == pytest.approx(0.113, abs=1e-6)
    start = track.time_s[0]
    assert track.photo_times_s - start == pytest.approx([(0.0 + 0.113) / 2, (0.288 + 0.402) / 2], abs=1e-6)


def test_csv_rows_number_file_lines_and_name_a_field_over_the_csv_limit(tmp_path):
    import csv
    import io

    from capture.track import csv_rows

    text = 'a,b\n1,"two\nlines"\n3,4\n'
    assert list(csv_rows(csv.reader(io.StringIO(text)), "x.csv")) == [(1, ["a", "b"]), (3, ["1", "two\nlines"]),
                                                                     (4, ["3", "4"])]
    with_header = csv.DictReader(io.StringIO(text + "5," + "x" * 200_000 + "\n"))
    rows = csv_rows(with_header, "x.csv")
    assert [next(rows)[0], next(rows)[0]] == [3, 4]
    with pytest.raises(LogFormatError, match=r"^x\.csv:5: field larger than field limit"):
        next(rows)
