"""``Track``: one time-ordered table of aircraft/gimbal telemetry, whatever the source.

Time is ``float64`` **seconds since 1970-01-01T00:00:00 UTC** (``time_s``), which keeps sub-microsecond
resolution for present-day dates and makes interpolation plain ``numpy``. Two exceptions are flagged by
``Track.clock``: ``"relative"`` (a source without a wall-clock date, e.g. a Mini SRT read without an anchor:
seconds from its start) and ``"camera"`` (photo EXIF times: the camera's own clock, read as if it were UTC).

Every row has every column; a value a row does not carry is NaN. So a reader for a stream of mixed messages
(position at 10 Hz, gimbal at 50 Hz) simply emits one row per message with the fields that message has and
lets :meth:`Track.from_rows` sort them; interpolation uses, per field, only the rows where it is finite.
Photo events (shutter times on the track's clock) are a separate sorted list.
"""

from __future__ import annotations

import csv
import math
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from cliutil.atomic import write_text_atomic
from flightplan.geodesy import validate_latlon

#: The kinds of log :mod:`capture.logs` reads into a Track (its readers' names, ``--kind`` of the command line).
LOG_KINDS = ("photos", "srt", "litchi", "airdata", "duml")

# Column name -> meaning (unit, frame). Heights: above take-off (barometric/relative) and "absolute" as the
# source calls it (DJI AbsoluteAltitude, Airdata altitude above sea level...). Angles: DJI NED ZYX degrees,
# see capture/attitude.py; gimbal angles are absolute (earth frame).
FIELDS: dict[str, str] = {
    "lat_deg": "WGS84 latitude, degrees",
    "lon_deg": "WGS84 longitude, degrees",
    "height_above_takeoff_m": "height above the take-off point, metres",
    "absolute_height_m": "absolute height as the source defines it, metres",
    "aircraft_yaw_deg": "aircraft yaw, NED degrees",
    "aircraft_pitch_deg": "aircraft pitch, NED degrees",
    "aircraft_roll_deg": "aircraft roll, NED degrees",
    "gimbal_yaw_deg": "gimbal yaw (absolute), NED degrees",
    "gimbal_pitch_deg": "gimbal pitch, degrees (0 horizon, -90 nadir)",
    "gimbal_roll_deg": "gimbal roll, NED degrees",
    "speed_m_s": "horizontal ground speed, m/s",
}
CLOCKS = ("utc", "relative", "camera")
#: How a merged track's source names its parts (:meth:`Track.concat`).
MERGED_SOURCES = " + "


class LogFormatError(ValueError):
    """A file that cannot be read at all; the message names the file and the line or byte offset."""


@contextmanager
def csv_errors(source, reader, first_line: int = 1):
    """Inside the block, an error of the ``csv`` module (a field over its size limit, a NUL byte) raises
    :class:`LogFormatError` naming ``source`` and the line ``reader`` stopped at (``first_line``: the file line
    of the reader's first line)."""
    try:
        yield
    except csv.Error as error:
        lines_read = getattr(reader, "reader", reader).line_num  # a DictReader counts only the rows it returned
        raise LogFormatError(f"{source}:{lines_read + first_line - 1}: {error}") from None


def csv_rows(reader, source, first_line: int = 1) -> Iterator[tuple[int, list]]:
    """``(file line, row)`` of each row of a ``csv`` ``reader`` (or ``DictReader``), errors as :func:`csv_errors`."""
    rows = iter(reader)
    while True:
        with csv_errors(source, reader, first_line):
            row = next(rows, None)
        if row is None:
            return
        yield reader.line_num + first_line - 1, row


@dataclass(frozen=True)
class Problem:
    """Something a reader could not use: where (file, 1-based line or None) and why."""

    file: str
    line: int | None
    reason: str

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}" if self.line is not None else self.file
        return f"{where}: {self.reason}"


@dataclass
class ReadReport:
    """What a reader did with a source: rows used, rows rejected (with file:line and reason), notes."""

    source: str
    kind: str
    rows_read: int = 0
    rows_used: int = 0
    rejected: list[Problem] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def reject(self, line: int | None, reason: str) -> None:
        self.rejected.append(Problem(self.source, line, reason))

    def reasons(self) -> Counter:
        """Count of rejected rows per reason (the text before any ':' detail)."""
        return Counter(problem.reason.split(":")[0] for problem in self.rejected)

    def summary(self) -> str:
        """One line: source, kind, rows used/read and rejects grouped by reason."""
        text = f"{self.source} [{self.kind}]: {self.rows_used} of {self.rows_read} rows used"
        if self.rejected:
            text += "; rejected " + ", ".join(f"{n} {reason}" for reason, n in self.reasons().most_common())
        return text


def name_list(names: list[str], shown: int = 10) -> str:
    """``a, b, c`` -- the first ``shown`` names, then `` ...`` if there are more (for one-line summaries)."""
    return ", ".join(names[:shown]) + (" ..." if len(names) > shown else "")


def position_problem(lat_deg: float, lon_deg: float) -> str | None:
    """Why a WGS84 position (degrees) cannot be used, as a reject reason, or None when it can.

    Every log reader checks its positions here, so a reason reads the same whatever the source.
    """
    try:
        validate_latlon(lat_deg, lon_deg)
    except ValueError as error:
        return f"position out of range: {error}"
    return None


@dataclass(frozen=True)
class Home:
    """Take-off / home point: WGS84 degrees and the absolute height there (NaN if unknown)."""

    lat_deg: float
    lon_deg: float
    absolute_height_m: float = math.nan


@dataclass
class Track:
    """Time-ordered telemetry columns; see the module docstring for time and NaN conventions."""

    time_s: np.ndarray
    columns: dict[str, np.ndarray]
    photo_times_s: np.ndarray
    fields: frozenset[str]
    report: ReadReport
    clock: str = "utc"
    home: Home | None = None
    event_time_error_s: float = 0.0  # how far a photo event may sit from the true shutter time

    @classmethod
    def from_rows(
        cls,
        time_s,
        columns: dict[str, np.ndarray],
        report: ReadReport,
        *,
        photo_times_s=(),
        clock: str = "utc",
        home: Home | None = None,
        event_time_error_s: float = 0.0,
    ) -> "Track":
        """Build a track from unsorted rows; missing columns become NaN, ``fields`` = columns with data."""
        time_s = np.asarray(time_s, dtype=np.float64)
        unknown = set(columns) - set(FIELDS)
        if unknown:
            raise ValueError(f"unknown track columns {sorted(unknown)}; known: {sorted(FIELDS)}")
        if clock not in CLOCKS:
            raise ValueError(f"clock must be one of {CLOCKS}, got {clock!r}")
        order = np.argsort(time_s, kind="stable")
        full = {}
        for name in FIELDS:
            values = np.asarray(columns.get(name, np.full(len(time_s), np.nan)), dtype=np.float64)
            if values.shape != time_s.shape:
                raise ValueError(f"column {name} has {values.shape} values for {time_s.shape} times")
            full[name] = values[order]
        present = frozenset(name for name, values in full.items() if np.isfinite(values).any())
        photos = np.sort(np.asarray(photo_times_s, dtype=np.float64))
        return cls(time_s[order], full, photos, present, report, clock, home, event_time_error_s)

    @classmethod
    def concat(cls, tracks: list["Track"]) -> "Track":
        """Merge tracks on the same clock into one (rows and photo events sorted by time)."""
        if not tracks:
            raise ValueError("no tracks to merge")
        clocks = {track.clock for track in tracks}
        if len(clocks) != 1:
            raise ValueError(f"cannot merge tracks on different clocks: {sorted(clocks)}")
        if len(tracks) == 1:
            return tracks[0]
        report = ReadReport(MERGED_SOURCES.join(t.report.source for t in tracks), "merged",
                            sum(t.report.rows_read for t in tracks), sum(t.report.rows_used for t in tracks),
                            [p for t in tracks for p in t.report.rejected], [n for t in tracks for n in t.report.notes])
        merged = cls.from_rows(
            np.concatenate([t.time_s for t in tracks]),
            {name: np.concatenate([t.columns[name] for t in tracks]) for name in FIELDS},
            report,
            photo_times_s=np.concatenate([t.photo_times_s for t in tracks]),
            clock=tracks[0].clock,
            home=next((t.home for t in tracks if t.home is not None), None),
            event_time_error_s=max(t.event_time_error_s for t in tracks),
        )
        return merged

    def __len__(self) -> int:
        return len(self.time_s)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def has(self, name: str) -> bool:
        """True if the source really carried this field (at least one finite value)."""
        return name in self.fields

    def positions_mask(self) -> np.ndarray:
        """Rows with a usable horizontal position (finite lat/lon)."""
        return np.isfinite(self["lat_deg"]) & np.isfinite(self["lon_deg"])

    def take_off(self) -> Home | None:
        """The home point if the source gave one, else the first row with a position."""
        if self.home is not None:
            return self.home
        rows = np.flatnonzero(self.positions_mask())
        if len(rows) == 0:
            return None
        first = rows[0]
        return Home(float(self["lat_deg"][first]), float(self["lon_deg"][first]))

    def to_csv_text(self) -> str:
        """The track as CSV text: ``utc_time`` (ISO) or ``time_s`` for non-UTC clocks, then every field."""
        names = list(FIELDS)
        time_header = "utc_time" if self.clock == "utc" else f"time_s_{self.clock}"
        lines = [",".join([time_header, "photo_event", *names])]
        photo_rows = set(np.searchsorted(self.time_s, self.photo_times_s).tolist())
        for row, t in enumerate(self.time_s):
            cells = [format_utc(t) if self.clock == "utc" else f"{t:.6f}", "1" if row in photo_rows else "0"]
            cells += [format_number(self.columns[name][row]) for name in names]
            lines.append(",".join(cells))
        return "\n".join(lines) + "\n"

    def write_csv(self, path) -> None:
        """Write :meth:`to_csv_text` atomically."""
        write_text_atomic(path, self.to_csv_text())

    def write_kml(self, path) -> None:
        """Write the track as a KML LineString (height above take-off, relative to ground) atomically; the document
        (the layer GIS tools show) is named after the source files' names (:func:`source_name`)."""
        rows = self.positions_mask()
        heights = np.nan_to_num(self["height_above_takeoff_m"][rows])
        coords = " ".join(f"{lon:.8f},{lat:.8f},{h:.2f}" for lat, lon, h in
                          zip(self["lat_deg"][rows], self["lon_deg"][rows], heights))
        name = escape_xml(source_name(self.report.source))
        text = (
            '<?xml version="1.0" encoding="UTF-8"?>\n<kml xmlns="http://www.opengis.net/kml/2.2"><Document>'
            f"<name>{name}</name><Placemark><name>track</name><LineString><altitudeMode>relativeToGround"
            f"</altitudeMode><coordinates>{coords}</coordinates></LineString></Placemark></Document></kml>\n"
        )
        write_text_atomic(path, text)


def source_name(source: str) -> str:
    """A reader's ``source`` (a path, or merged paths joined by `` + ``) as file names without folder or extension:
    ``/home/me/logs/DJIFlightRecord_2024.txt`` -> ``DJIFlightRecord_2024``."""
    return MERGED_SOURCES.join(Path(part).stem for part in source.split(MERGED_SOURCES))


def format_utc(time_s: float) -> str:
    """Seconds since the Unix epoch -> ISO 8601 UTC with microseconds and ``Z``."""
    micros = int(round(float(time_s) * 1e6))
    stamp = datetime.fromtimestamp(micros // 1_000_000, tz=timezone.utc).replace(microsecond=micros % 1_000_000)
    return stamp.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def parse_utc(text: str) -> float:
    """ISO 8601 date-time -> seconds since the Unix epoch; naive times are UTC. Raises ValueError."""
    cleaned = text.strip().replace("/", "-")
    if cleaned.endswith(("Z", "z")):
        cleaned = cleaned[:-1] + "+00:00"
    stamp = datetime.fromisoformat(cleaned)
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=timezone.utc)
    return stamp.timestamp()


def format_number(value: float) -> str:
    """A float for CSV: empty for NaN, otherwise up to 9 decimals without trailing zeros."""
    if not np.isfinite(value):
        return ""
    text = f"{value:.9f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def escape_xml(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
