"""Write a ``Track`` as a Litchi flight-log CSV, an Airdata CSV or a DJI SRT (for tests, benchmarks and
the virtual drone). The formats follow the real headers (``litchi.md`` §3, ``dji-telemetry.md`` §5), so the
readers in this package read them back; photo events become a 1 on the first row at or after each event."""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np

from ..atomic import write_text_atomic
from ..track import Track
from .flightcsv import LENGTH_TO_M, SPEED_TO_M_S


def photo_flags(track: Track) -> np.ndarray:
    """1 on the first row at or after each photo event, else 0."""
    flags = np.zeros(len(track), dtype=int)
    rows = np.searchsorted(track.time_s, track.photo_times_s, side="left")
    flags[rows[rows < len(track)]] = 1
    return flags


def clock_text(time_s: float, digits: int) -> str:
    """``YYYY-MM-DD HH:MM:SS`` plus ``digits`` decimals of the second (truncated, as loggers do)."""
    stamp = datetime.fromtimestamp(np.floor(time_s * 10**digits) / 10**digits, tz=timezone.utc)
    text = stamp.strftime("%Y-%m-%d %H:%M:%S.%f")
    return text[: len(text) - 6 + digits] if digits else text[:19]


def cell(value: float, decimals: int) -> str:
    return "" if not np.isfinite(value) else f"{value:.{decimals}f}"


def litchi_csv_text(track: Track) -> str:
    """Metric Litchi flight log (``altitude(m)``, ``speed(mps)``, gimbal as tenths in ``gimbal*Raw``)."""
    header = ("latitude,longitude,altitude(m),speed(mps),time(millisecond),datetime(utc),pitch(deg),roll(deg),"
              "yaw(deg),isflying,istakingphoto,gimbalPitchRaw,gimbalRollRaw,gimbalYawRaw,home_latitude,home_longitude")
    home = track.take_off()
    flags = photo_flags(track)
    lines = [header]
    for k, t in enumerate(track.time_s):
        c = {name: values[k] for name, values in track.columns.items()}
        raw = [cell(np.round(c[f"gimbal_{axis}_deg"] * 10), 0) for axis in ("pitch", "roll", "yaw")]
        lines.append(",".join([
            cell(c["lat_deg"], 9), cell(c["lon_deg"], 9), cell(c["height_above_takeoff_m"], 3),
            cell(c["speed_m_s"], 3), str(int(round((t - track.time_s[0]) * 1000))), clock_text(t, 3),
            cell(c["aircraft_pitch_deg"], 2), cell(c["aircraft_roll_deg"], 2), cell(c["aircraft_yaw_deg"], 2),
            "1", str(flags[k]), *raw, cell(home.lat_deg, 9), cell(home.lon_deg, 9)]))
    return "\n".join(lines) + "\n"


def airdata_csv_text(track: Track, units: str = "imperial", start_elapsed_ms: int = 0) -> str:
    """Airdata export with whole-second ``datetime(utc)``, leading-space headers and values, chosen units."""
    length, speed = ("feet", "mph") if units == "imperial" else ("meters", "m/s")
    to_length, to_speed = 1.0 / LENGTH_TO_M[length], 1.0 / SPEED_TO_M_S[speed]
    header = (f"time(millisecond),datetime(utc),latitude,longitude,height_above_takeoff({length}),"
              f"altitude_above_seaLevel({length}),speed({speed}), compass_heading(degrees), pitch(degrees),"
              " roll(degrees),isPhoto,gimbal_heading(degrees),gimbal_pitch(degrees),gimbal_roll(degrees),message")
    flags = photo_flags(track)
    lines = [header]
    for k, t in enumerate(track.time_s):
        c = {name: values[k] for name, values in track.columns.items()}
        lines.append(",".join([
            str(start_elapsed_ms + int(round((t - track.time_s[0]) * 1000))), clock_text(t, 0),
            cell(c["lat_deg"], 12), cell(c["lon_deg"], 12), cell(c["height_above_takeoff_m"] * to_length, 6),
            cell(c["absolute_height_m"] * to_length, 6), cell(c["speed_m_s"] * to_speed, 4),
            cell(c["aircraft_yaw_deg"] % 360.0, 2), " " + cell(c["aircraft_pitch_deg"], 2),
            " " + cell(c["aircraft_roll_deg"], 2), str(flags[k]), cell(c["gimbal_yaw_deg"] % 360.0, 2),
            cell(c["gimbal_pitch_deg"], 2), cell(c["gimbal_roll_deg"], 2), ""]))
    return "\n".join(lines) + "\n"


def srt_timecode(seconds: float) -> str:
    millis = int(round(seconds * 1000))
    return f"{millis // 3600000:02d}:{millis // 60000 % 60:02d}:{millis // 1000 % 60:02d},{millis % 1000:03d}"


def srt_text(track: Track, style: str = "compact") -> str:
    """SRT cues, one per row: ``compact`` (P4 RTK style, no date, F.PRY/G.PRY) or ``dated`` (Mavic 3 style)."""
    cues = []
    t0 = track.time_s[0]
    ends = np.append(track.time_s[1:], track.time_s[-1] + 1.0)
    for k, t in enumerate(track.time_s):
        c = {name: values[k] for name, values in track.columns.items()}
        timing = f"{k + 1}\n{srt_timecode(t - t0)} --> {srt_timecode(ends[k] - t0)}\n"
        if style == "compact":
            data = (f"F/2.8, SS 400, ISO 100, EV 0, GPS ({c['lon_deg']:.8f}, {c['lat_deg']:.8f}, 18), "
                    f"D 0.00m, H {c['height_above_takeoff_m']:.2f}m, H.S {c['speed_m_s']:.2f}m/s, V.S 0.00m/s, "
                    f"F.PRY ({c['aircraft_pitch_deg']:.1f}°, {c['aircraft_roll_deg']:.1f}°, {c['aircraft_yaw_deg']:.1f}°), "
                    f"G.PRY ({c['gimbal_pitch_deg']:.1f}°, {c['gimbal_roll_deg']:.1f}°, {c['gimbal_yaw_deg']:.1f}°)")
        elif style == "dated":
            data = (f'<font size="28">FrameCnt: {k + 1}, DiffTime: 100ms\n{clock_text(t, 3)}\n[iso: 100] '
                    f"[latitude: {c['lat_deg']:.8f}] [longitude: {c['lon_deg']:.8f}] "
                    f"[rel_alt: {c['height_above_takeoff_m']:.3f} abs_alt: {c['absolute_height_m']:.3f}] "
                    f"[gb_yaw: {c['gimbal_yaw_deg']:.1f} gb_pitch: {c['gimbal_pitch_deg']:.1f} "
                    f"gb_roll: {c['gimbal_roll_deg']:.1f}] </font>")
        else:
            raise ValueError(f"unknown SRT style {style!r}; known: compact, dated")
        cues.append(timing + data + "\n")
    return "\n".join(cues)


def write_litchi_csv(track: Track, path) -> None:
    write_text_atomic(path, litchi_csv_text(track))


def write_airdata_csv(track: Track, path, units: str = "imperial") -> None:
    write_text_atomic(path, airdata_csv_text(track, units))


def write_srt(track: Track, path, style: str = "compact") -> None:
    write_text_atomic(path, srt_text(track, style))
