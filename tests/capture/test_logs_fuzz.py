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
