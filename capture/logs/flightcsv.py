"""Litchi flight-log CSV and Airdata CSV -> ``Track``.

Columns are found by header name and converted by their unit suffix (``altitude(feet)``, ``speed(mph)``,
``height_above_takeoff(meters)`` ...), never by position; header cells and values are whitespace-stripped
(Airdata writes ``" pitch(degrees)"`` and ``" 3.3"``). Time: ``datetime(utc)``; when every stamp is a whole
second (Airdata), it is refined with ``time(millisecond)`` (see :func:`refine_whole_seconds`). Rows without
a GPS fix (latitude, longitude = 0, 0) are rejected for position; photo events are the rising edges of
``istakingphoto`` (Litchi) / ``isPhoto`` (Airdata), placed midway between the last 0 row and the first 1 row.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..attitude import wrap_deg
from ..track import Home, LogFormatError, ReadReport, Track, csv_rows, parse_utc, position_problem

LENGTH_TO_M = {"feet": 0.3048, "ft": 0.3048, "m": 1.0, "meters": 1.0, "metres": 1.0, "meter": 1.0, "metre": 1.0}
SPEED_TO_M_S = {"mph": 0.44704, "mps": 1.0, "m/s": 1.0, "kmh": 1 / 3.6, "km/h": 1 / 3.6, "kph": 1 / 3.6,
                "knots": 0.514444, "kn": 0.514444, "ft/s": 0.3048, "fps": 0.3048}
ANGLE_UNITS = {"deg": 1.0, "degrees": 1.0, "degree": 1.0}
HEADER_CELL = re.compile(r"^\s*([^()]*?)\s*(?:\(([^()]*)\))?\s*$")


@dataclass(frozen=True)
class ColumnSpec:
    """Where a track field comes from: header name (lower case), unit table, scale for raw tenths, wrap."""

    field: str
    names: tuple[str, ...]
    units: dict[str, float] | None = None
    raw_scale: float = 1.0
    wrap: bool = False


AIRDATA_COLUMNS = (
    ColumnSpec("lat_deg", ("latitude",)),
    ColumnSpec("lon_deg", ("longitude",)),
    ColumnSpec("height_above_takeoff_m", ("height_above_takeoff",), LENGTH_TO_M),
    ColumnSpec("absolute_height_m", ("altitude_above_sealevel",), LENGTH_TO_M),
    ColumnSpec("speed_m_s", ("speed",), SPEED_TO_M_S),
    ColumnSpec("aircraft_yaw_deg", ("compass_heading",), ANGLE_UNITS, wrap=True),
    ColumnSpec("aircraft_pitch_deg", ("pitch",), ANGLE_UNITS),
    ColumnSpec("aircraft_roll_deg", ("roll",), ANGLE_UNITS),
    ColumnSpec("gimbal_yaw_deg", ("gimbal_heading",), ANGLE_UNITS, wrap=True),
    ColumnSpec("gimbal_pitch_deg", ("gimbal_pitch",), ANGLE_UNITS),
    ColumnSpec("gimbal_roll_deg", ("gimbal_roll",), ANGLE_UNITS),
)
LITCHI_COLUMNS = (
    ColumnSpec("lat_deg", ("latitude",)),
    ColumnSpec("lon_deg", ("longitude",)),
    ColumnSpec("height_above_takeoff_m", ("altitude",), LENGTH_TO_M),
    ColumnSpec("speed_m_s", ("speed",), SPEED_TO_M_S),
    ColumnSpec("aircraft_yaw_deg", ("yaw",), ANGLE_UNITS, wrap=True),
    ColumnSpec("aircraft_pitch_deg", ("pitch",), ANGLE_UNITS),
    ColumnSpec("aircraft_roll_deg", ("roll",), ANGLE_UNITS),
    # Litchi has no gimbal angles in degrees; the *Raw columns are tenths of a degree.
    ColumnSpec("gimbal_yaw_deg", ("gimbalyawraw",), raw_scale=0.1, wrap=True),
    ColumnSpec("gimbal_pitch_deg", ("gimbalpitchraw",), raw_scale=0.1),
    ColumnSpec("gimbal_roll_deg", ("gimbalrollraw",), raw_scale=0.1),
)
FORMATS = {"airdata": (AIRDATA_COLUMNS, "isphoto"), "litchi": (LITCHI_COLUMNS, "istakingphoto")}


def sniff_flight_csv(header_line: str) -> str | None:
    """'litchi', 'airdata' or None from a CSV header line."""
    names = {parse_header_cell(cell)[0] for cell in header_line.split(",")}
    if "datetime" not in names or not {"latitude", "longitude"} <= names:
        return None
    if "istakingphoto" in names or names & {"dronetype", "planename", "isflying"}:
        return "litchi"
    if "isphoto" in names or "height_above_takeoff" in names:
        return "airdata"
    return None


def parse_header_cell(cell: str) -> tuple[str, str]:
    """``' xSpeed(mph)'`` -> ``('xspeed', 'mph')``: lower-case name and unit ('' if none)."""
    match = HEADER_CELL.match(cell)
    if not match:
        return cell.strip().lower(), ""
    return match.group(1).lower(), (match.group(2) or "").strip().lower()


def read_flight_csv(path, kind: str | None = None) -> Track:
    """Read a Litchi or Airdata CSV (``kind`` None: detect from the header)."""
    path = Path(path)
    text = path.read_text(encoding="utf-8-sig", errors="replace")
    lines = text.splitlines()
    if not lines:
        raise LogFormatError(f"{path}:1: empty file, expected a CSV header")
    kind = kind or sniff_flight_csv(lines[0])
    if kind not in FORMATS:
        raise LogFormatError(f"{path}:1: not a Litchi or Airdata flight-log header (expected datetime(utc), "
                             "latitude, longitude and istakingphoto or isPhoto)")
    specs, photo_flag = FORMATS[kind]
    report = ReadReport(str(path), kind)
    header = [parse_header_cell(cell) for cell in next(csv_rows(csv.reader([lines[0]]), path))[1]]
    columns = locate_columns(path, header, specs)
    time_col = find_column(header, "datetime", "utc")
    if time_col is None:
        raise LogFormatError(f"{path}:1: no 'datetime(utc)' column")
    elapsed_col = find_column(header, "time", "millisecond")
    flag_col = find_column(header, photo_flag)
    home = litchi_home(header, lines, path) if kind == "litchi" else None

    rows = parse_rows(path, lines, header, columns, time_col, elapsed_col, flag_col, report)
    times = refine_whole_seconds(rows["datetime"], rows["elapsed_ms"], path, report)
    fix = (rows["lat_deg"] != 0.0) | (rows["lon_deg"] != 0.0)
    for line in rows["line"][~fix]:
        report.reject(int(line), "no GPS fix: latitude, longitude = 0, 0")
    photos = rising_edge_times(times, rows["flag"])
    report.rows_used = int(fix.sum())
    values = {name: rows[name][fix] for name in columns}
    row_step = float(np.median(np.diff(times))) if len(times) > 1 else 0.0
    return Track.from_rows(times[fix], values, report, photo_times_s=photos, home=home,
                           event_time_error_s=0.5 * row_step)


def locate_columns(path, header, specs) -> dict[str, tuple[int, float, ColumnSpec]]:
    """Field -> (column index, unit factor, spec) for every spec present in the header."""
    found = {}
    for spec in specs:
        index = next((i for i, (name, _) in enumerate(header) if name in spec.names), None)
        if index is None:
            continue
        unit = header[index][1]
        factor = spec.raw_scale
        if spec.units is not None:
            if unit not in spec.units:
                raise LogFormatError(f"{path}:1: column {index + 1} '{header[index][0]}({unit})': unknown unit "
                                     f"'{unit}', expected one of {sorted(spec.units)}")
            factor = spec.units[unit]
        found[spec.field] = (index, factor, spec)
    for required in ("lat_deg", "lon_deg"):
        if required not in found:
            raise LogFormatError(f"{path}:1: no {required.split('_')[0]}itude column")
    return found


def find_column(header, name: str, unit: str | None = None) -> int | None:
    return next((i for i, (n, u) in enumerate(header) if n == name and (unit is None or u == unit)), None)


def parse_rows(path, lines, header, columns, time_col, elapsed_col, flag_col, report) -> dict[str, np.ndarray]:
    """Parse every data line; rows with an unreadable time or position are rejected with file:line."""
    out: dict[str, list] = {name: [] for name in ("line", "datetime", "elapsed_ms", "flag", *columns)}
    width = len(header)
    for line_no, cells in csv_rows(csv.reader(io.StringIO("\n".join(lines[1:]))), path, first_line=2):
        if not cells or all(not c.strip() for c in cells):
            continue
        report.rows_read += 1
        if len(cells) < width:
            report.reject(line_no, f"truncated row: {len(cells)} cells, header has {width}")
            continue
        try:
            stamp = parse_utc(cells[time_col])
        except ValueError:
            report.reject(line_no, f"bad datetime(utc): expected YYYY-MM-DD HH:MM:SS[.fff], got {cells[time_col]!r}")
            continue
        row = {"line": line_no, "datetime": stamp}
        try:
            row["elapsed_ms"] = cell_number(cells, elapsed_col, "time(millisecond)")
            row["flag"] = cell_number(cells, flag_col, "photo flag")
            for name, (index, factor, spec) in columns.items():
                value = cell_number(cells, index, header_label(header[index])) * factor
                row[name] = float(wrap_deg(value)) if spec.wrap and math.isfinite(value) else value
        except ValueError as error:
            report.reject(line_no, f"bad number: {error}")
            continue
        if not (math.isfinite(row["lat_deg"]) and math.isfinite(row["lon_deg"])):
            report.reject(line_no, "missing latitude/longitude")
            continue
        if problem := position_problem(row["lat_deg"], row["lon_deg"]):
            report.reject(line_no, problem)
            continue
        for name, value in row.items():
            out[name].append(value)
    if not out["line"]:
        raise LogFormatError(f"{path}: no readable data rows ({len(report.rejected)} rejected; first: "
                             f"{report.rejected[0] if report.rejected else 'none'})")
    return {name: np.asarray(values, dtype=np.float64) for name, values in out.items()}


def header_label(cell: tuple[str, str]) -> str:
    name, unit = cell
    return f"{name}({unit})" if unit else name


def cell_number(cells, index: int | None, label: str) -> float:
    """The number in ``cells[index]``; NaN if the column is absent or the cell empty/'n/a'."""
    if index is None or index >= len(cells):
        return math.nan
    text = cells[index].strip()
    if text == "" or text.lower() in ("n/a", "nan", "(null)", "null"):
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"column '{label}': expected a number, got {text[:40]!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"column '{label}': not a finite number: {text[:40]!r}")
    return value


def refine_whole_seconds(datetime_s: np.ndarray, elapsed_ms: np.ndarray, path, report: ReadReport) -> np.ndarray:
    """Row times: ``datetime`` as is when it has sub-seconds, else start + ``time(millisecond)``.

    Airdata's ``datetime(utc)`` is truncated to the second; with ``t = start + elapsed``,
    ``floor(t) == datetime`` for every row confines ``start`` to the intersection of the intervals
    ``[datetime - elapsed, datetime - elapsed + 1)``, which at 10 Hz is ~0.1 s wide; we take its middle.
    """
    has_fraction = np.any(np.abs(datetime_s - np.round(datetime_s)) > 1e-6)
    if has_fraction or not np.isfinite(elapsed_ms).all():
        if not has_fraction:
            report.notes.append("datetime(utc) has whole seconds only and no time(millisecond): 1 s resolution")
        return datetime_s
    elapsed_s = elapsed_ms / 1000.0
    if np.any(np.diff(elapsed_s) < 0):
        bad = int(np.flatnonzero(np.diff(elapsed_s) < 0)[0]) + 1
        report.notes.append(f"time(millisecond) goes backwards near data row {bad + 1}; using datetime(utc) only")
        return datetime_s
    low = np.max(datetime_s - elapsed_s)
    high = np.min(datetime_s - elapsed_s + 1.0)
    if low >= high:
        low, high = np.max(datetime_s - elapsed_s - 0.5), np.min(datetime_s - elapsed_s + 0.5)
        if low >= high:
            raise LogFormatError(f"{path}: datetime(utc) and time(millisecond) disagree by more than 1 s "
                                 "(neither truncated nor rounded seconds fit every row)")
        report.notes.append("datetime(utc) looks rounded (not truncated) to the second")
    start = 0.5 * (low + high)
    report.notes.append(f"sub-second times from time(millisecond); start known to +-{(high - low) / 2:.3f} s")
    return start + elapsed_s


def rising_edge_times(times: np.ndarray, flag: np.ndarray) -> np.ndarray:
    """Photo events: midway between the last row with flag 0 and the first row with flag 1."""
    on = np.nan_to_num(flag) > 0.5
    edges = np.flatnonzero(on[1:] & ~on[:-1]) + 1
    events = 0.5 * (times[edges - 1] + times[edges])
    if len(on) and on[0]:
        events = np.concatenate([[times[0]], events])
    return events


def litchi_home(header, lines, path) -> Home | None:
    """Litchi's home_latitude/home_longitude from the first row that has them non-zero and in range."""
    lat_col, lon_col = find_column(header, "home_latitude"), find_column(header, "home_longitude")
    if lat_col is None or lon_col is None:
        return None
    for _, cells in csv_rows(csv.reader(io.StringIO("\n".join(lines[1:200]))), path, first_line=2):
        try:
            lat, lon = cell_number(cells, lat_col, "home_latitude"), cell_number(cells, lon_col, "home_longitude")
        except ValueError:
            continue
        if (lat, lon) != (0.0, 0.0) and not position_problem(lat, lon):
            return Home(lat, lon)
    return None
