"""DJI SRT subtitle telemetry -> ``Track``, for every style in the samples.

A cue is a block of lines separated by blank lines: an index, an optional ``HH:MM:SS,mmm --> ...`` timecode,
then data (``<font>`` tags removed). Fields are found by pattern, not position:

* compact (Mini, P4P, P4 RTK): ``GPS (lon, lat, sats)``, ``H 200.70m`` (above take-off), ``H.S 0.00m/s``,
  ``HOME (lon, lat[, alt m])``, ``F.PRY (pitch°, roll°, yaw°)`` aircraft and ``G.PRY (...)`` gimbal;
* legacy (Mavic Pro): ``HOME(lon,lat) YYYY.MM.DD HH:MM:SS`` / ``GPS(lon,lat,sats) BAROMETER:1.9``;
* M300: ``GPS(lat,lon,0.0M) BAROMETER:0.3M`` -- the third field ending in ``M`` marks the reversed order;
* bracketed (Mavic 2/Air 2/Air 2S/Mavic 3): ``[latitude: ..] [longitude: ..]`` (or the ``longtitude`` typo),
  ``[altitude: ..]`` (read as absolute), ``[rel_alt: .. abs_alt: ..]``, ``[gb_yaw: .. gb_pitch: .. gb_roll: ..]``.

Time: a date line (``YYYY-MM-DD HH:MM:SS,mmm,uuu``, ``YYYY.MM.DD HH:MM:SS[,mmm,uuu]``, ``... HH:MM:SS.mmm``) is
the aircraft's clock, which DJI keeps in local time: ``utc_offset_h`` converts it (default 0, noted in the
report). Styles without a date need ``start_time_s`` (UTC of cue time 0); without it the track's clock is
``"relative"`` (seconds from the video start) and the report says so.
"""

from __future__ import annotations

import math
import re
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..attitude import wrap_deg
from ..track import Home, LogFormatError, ReadReport, Track, position_problem

NUMBER = r"[-+]?\d+(?:\.\d+)?"
TIMECODE = re.compile(r"^(\d+):(\d{2}):(\d{2})[,.](\d{1,3})\s*-->\s*(\d+):(\d{2}):(\d{2})[,.](\d{1,3})$")
DATE = re.compile(r"(\d{4})[-.](\d{1,2})[-.](\d{1,2})\s+(\d{1,2}):(\d{2}):(\d{2})(?:[,.](\d{1,3}))?(?:,(\d{1,3}))?")
GPS = re.compile(rf"GPS\s*\(\s*({NUMBER})\s*,\s*({NUMBER})\s*(?:,\s*({NUMBER})\s*(M)?\s*)?\)", re.IGNORECASE)
HOME = re.compile(rf"HOME\s*\(\s*({NUMBER})\s*,\s*({NUMBER})\s*(?:,\s*({NUMBER})\s*m\s*)?\)", re.IGNORECASE)
HEIGHT = re.compile(rf"(?:^|[\s,])H\s+({NUMBER})\s*m\b")
BAROMETER = re.compile(rf"(?:BAROMETER|Hb)\s*:\s*({NUMBER})", re.IGNORECASE)
HSPEED = re.compile(rf"H\.S\s+({NUMBER})\s*m/s")
PRY = re.compile(rf"([FG])\.PRY\s*\(\s*({NUMBER})\D*?,\s*({NUMBER})\D*?,\s*({NUMBER})\D*?\)")
BRACKET_VALUE = re.compile(rf"(\w+)\s*:\s*({NUMBER})")
FONT_TAG = re.compile(r"</?font[^>]*>", re.IGNORECASE)
BRACKET_FIELDS = {
    "latitude": "lat_deg", "longitude": "lon_deg", "longtitude": "lon_deg",
    "rel_alt": "height_above_takeoff_m", "abs_alt": "absolute_height_m", "altitude": "absolute_height_m",
    "gb_yaw": "gimbal_yaw_deg", "gb_pitch": "gimbal_pitch_deg", "gb_roll": "gimbal_roll_deg",
}


def looks_like_srt(head: str) -> bool:
    """True if the text starts like a DJI SRT (an index line, then a timecode or a date line)."""
    lines = [line.strip() for line in head.lstrip("\ufeff").splitlines() if line.strip()][:3]
    return len(lines) >= 2 and lines[0].isdigit() and bool(TIMECODE.match(lines[1]) or DATE.match(lines[1]))


def split_cues(text: str) -> list[tuple[int, list[str]]]:
    """Blocks of non-blank lines with the 1-based line number of their first line."""
    blocks, current, start = [], [], 0
    for number, line in enumerate(text.splitlines(), start=1):
        if line.strip():
            if not current:
                start = number
            current.append(line.strip())
        elif current:
            blocks.append((start, current))
            current = []
    if current:
        blocks.append((start, current))
    return blocks


def read_srt(path, *, start_time_s: float | None = None, utc_offset_h: float = 0.0) -> Track:
    """Read a DJI SRT file in any known style; see the module docstring for the time rules."""
    path = Path(path)
    text = path.read_bytes().decode("utf-8-sig", errors="replace")
    cues = split_cues(text)
    if not cues:
        raise LogFormatError(f"{path}:1: empty SRT file")
    report = ReadReport(str(path), "srt")
    rows: list[dict] = []
    homes: list[tuple[float, float, float]] = []
    for line_no, lines in cues:
        report.rows_read += 1
        try:
            row, home = parse_cue(lines)
        except ValueError as error:
            report.reject(line_no, str(error))
            continue
        rows.append(row)
        if home is not None:
            homes.append(home)
    if not rows:
        raise LogFormatError(f"{path}: no readable cues; first problem: {report.rejected[0]}")
    times, clock = cue_times(rows, start_time_s, utc_offset_h, report)
    report.rows_used = len(rows)
    names = sorted({name for row in rows for name in row if name not in ("date_s", "cue_s")})
    columns = {name: np.array([row.get(name, math.nan) for row in rows]) for name in names}
    home = Home(*homes[0]) if homes else None
    return Track.from_rows(times, columns, report, clock=clock, home=home)


def parse_cue(lines: list[str]) -> tuple[dict, tuple[float, float, float] | None]:
    """One cue's lines -> (row of track fields + 'date_s'/'cue_s', home or None). Raises ValueError."""
    if not lines[0].isdigit():
        raise ValueError(f"cue does not start with an index number: {lines[0][:40]!r}")
    row: dict[str, float] = {}
    body = lines[1:]
    if body and (match := TIMECODE.match(body[0])):
        h, m, s, ms = (int(g) for g in match.groups()[:4])
        row["cue_s"] = h * 3600 + m * 60 + s + ms / 1000.0
        body = body[1:]
    data = FONT_TAG.sub(" ", " ".join(body))
    if match := DATE.search(data):
        row["date_s"] = date_seconds(match)
    parse_positions(data, row)
    home = None
    if match := HOME.search(data):
        home = (float(match.group(2)), float(match.group(1)), float(match.group(3)) if match.group(3) else math.nan)
    for match in PRY.finditer(data):
        prefix = "aircraft" if match.group(1) == "F" else "gimbal"
        pitch, roll, yaw = (float(g) for g in match.groups()[1:])
        row.update({f"{prefix}_pitch_deg": pitch, f"{prefix}_roll_deg": roll, f"{prefix}_yaw_deg": float(wrap_deg(yaw))})
    if "lat_deg" not in row or "lon_deg" not in row:
        raise ValueError(f"no position (GPS(...) or [latitude]/[longitude]) in cue: {data[:60]!r}")
    if problem := position_problem(row["lat_deg"], row["lon_deg"]):
        raise ValueError(problem)
    if "cue_s" not in row and "date_s" not in row:
        raise ValueError("cue has neither a timecode nor a date line")
    return row, home


def parse_positions(data: str, row: dict) -> None:
    """Fill lat/lon/heights/speed/gimbal from one cue's data text (all styles)."""
    if match := GPS.search(data):
        first, second = float(match.group(1)), float(match.group(2))
        if match.group(4):  # M300: GPS(lat, lon, altM)
            row["lat_deg"], row["lon_deg"] = first, second
        else:  # GPS(lon, lat, satellites)
            row["lon_deg"], row["lat_deg"] = first, second
    if match := HEIGHT.search(data):
        row["height_above_takeoff_m"] = float(match.group(1))
    elif match := BAROMETER.search(data):
        row["height_above_takeoff_m"] = float(match.group(1))
    if match := HSPEED.search(data):
        row["speed_m_s"] = float(match.group(1))
    for bracket in re.findall(r"\[([^\]]*)\]", data):
        for key, value in BRACKET_VALUE.findall(bracket):
            name = BRACKET_FIELDS.get(key.lower())
            if name is not None:
                row[name] = float(wrap_deg(float(value))) if name.endswith("yaw_deg") else float(value)


def date_seconds(match: re.Match) -> float:
    """A DATE match -> seconds since the epoch, reading the clock as UTC (offset applied later)."""
    year, month, day, hour, minute, second = (int(g) for g in match.groups()[:6])
    millis = int(match.group(7).ljust(3, "0")) if match.group(7) else 0
    micros = int(match.group(8).ljust(3, "0")) if match.group(8) else 0
    stamp = datetime(year, month, day, hour, minute, second, tzinfo=timezone.utc)
    return stamp.timestamp() + millis / 1e3 + micros / 1e6


def cue_times(rows: list[dict], start_time_s, utc_offset_h: float, report: ReadReport) -> tuple[np.ndarray, str]:
    """Row times and clock: the date lines (shifted by the UTC offset), else the anchored cue times."""
    dated = [row.get("date_s") for row in rows]
    if all(value is not None for value in dated):
        report.notes.append(f"SRT dates are the aircraft clock, read as UTC{utc_offset_h:+g} h")
        dates = np.array(dated) - utc_offset_h * 3600.0
        cues = [row.get("cue_s") for row in rows]
        if np.all(dates == np.floor(dates)) and all(cue is not None for cue in cues):
            return anchor_cues(dates, np.array(cues, dtype=float), report), "utc"
        repeats = int((np.diff(dates) <= 0).sum())
        if repeats:
            report.notes.append(f"{repeats} cues repeat or precede the previous cue's date (uneven aircraft clock)")
        return dates, "utc"
    if any(row.get("cue_s") is None for row in rows):
        raise LogFormatError(f"{report.source}: some cues have neither a date nor a timecode")
    cue = np.array([row["cue_s"] for row in rows])
    if start_time_s is None:
        report.notes.append("no wall-clock date in this SRT style: times are seconds from the video start; "
                            "give the video's start time (UTC) to anchor it")
        return cue, "relative"
    report.notes.append("cue times anchored at the given start time")
    return cue + float(start_time_s), "utc"


def anchor_cues(dates_s: np.ndarray, cues_s: np.ndarray, report: ReadReport) -> np.ndarray:
    """Whole-second dates + exact cue timecodes -> ``anchor + cue`` with the anchor that fits the dates.

    If every date is the truncated ``anchor + cue``, the anchor lies in the intersection of
    ``[date - cue, date - cue + 1)``; its middle is used. Where the aircraft clock ticks unevenly (dates repeat
    or skip a second against 1 s cues) no anchor fits all; the median ``date - cue`` + 0.5 s is used instead.
    """
    offsets = dates_s - cues_s
    low, high = offsets.max(), offsets.min() + 1.0
    if low < high:
        report.notes.append(f"times = cue timecode + anchor; anchor known to +-{(high - low) / 2:.3f} s")
        return cues_s + 0.5 * (low + high)
    anchor = float(np.median(offsets)) + 0.5
    report.notes.append(f"dates jitter by up to {low - high + 1.0:.0f} s against the cue timecodes; times = cue "
                        "timecode + median anchor")
    return cues_s + anchor
