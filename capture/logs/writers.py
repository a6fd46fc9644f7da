"""Write a ``Track`` as a Litchi flight-log CSV, an Airdata CSV, a DJI SRT or a raw DUML capture (for tests,
benchmarks and the virtual drone). The formats follow the real headers and layouts (``litchi.md`` §3,
``dji-telemetry.md`` §2 and §5), so the readers in this package read them back; photo events become a 1 (or a
camera-state shutter edge) on the first row at or after each event."""

from __future__ import annotations

import dataclasses
import math
from datetime import datetime, timezone

import numpy as np

from cliutil.atomic import write_text_atomic
from ..geotag import HEIGHT_UNKNOWN, take_off_frame
from ..messages import CameraState, GimbalParams, HomePoint, OsdGeneral, encode_message
from ..raw import atomic_capture
from ..track import Track
from .flightcsv import LENGTH_TO_M, SPEED_TO_M_S

# What a P3X-like aircraft sends besides the track's values (GPS_Atti mode, 14 satellites, camera idle).
OSD_PUSH = OsdGeneral(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, ctrl_info=6, latest_app_command=0,
                      controller_state=0, gps_satellites=14, gohome_reason=0, motor_start_fail=0, ctrl_state_ext=0,
                      battery_percent=80, ultrasonic_height_m=0.0, fly_time_s=0.0, motor_start_count=1,
                      battery_alarm1=0, battery_alarm2=0, version_match=1, product_type=2, imu_init_fail_reason=0)
CAMERA_PUSH = CameraState(status_flags=1 << 9, camera_mode=0, sd_total_mb=30000, sd_free_mb=20000,
                          remaining_shots=999, remaining_time_s=0, file_index_mode=0)


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
    """Metric Litchi flight log (``altitude(m)``, ``speed(mps)``, gimbal as tenths in ``gimbal*Raw``).

    ``altitude(m)`` is the track's ``height_above_takeoff_m``, as in Litchi's own logs: a barometric height above
    the take-off point, never a GPS or sea-level altitude (a Litchi log has no absolute height column, so the
    track's ``absolute_height_m`` is not written; use the SRT's ``abs_alt`` or a GPX export for that)."""
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


def duml_records(track: Track) -> list[tuple[float, object]]:
    """``(time_s, record)`` pushes an aircraft would send for ``track``, in time order: per row an OSD General
    (rows with a position), a Gimbal Params (rows with gimbal yaw) and a Camera State (``photo_state`` 1 on the
    first row at or after each photo event), and the take-off point as a Home Point once a second."""
    frame, height_datum = take_off_frame(track)
    h0 = math.nan if height_datum == HEIGHT_UNKNOWN else frame.h0_m
    home = HomePoint(frame.lon0_deg, frame.lat0_deg, h0, 1, 60, 0, 0, 0, 0, 0)
    flags = photo_flags(track)
    new_second = np.r_[True, np.diff(np.floor(track.time_s)) > 0]
    records = []
    for k, t in enumerate(track.time_s):
        row = {name: values[k] for name, values in track.columns.items()}
        if np.isfinite(row["lat_deg"]) and np.isfinite(row["lon_deg"]):
            records.append((t, osd_record(row)))
        if np.isfinite(row["gimbal_yaw_deg"]):
            records.append((t, GimbalParams(*np.nan_to_num([row["gimbal_pitch_deg"], row["gimbal_roll_deg"],
                                                            row["gimbal_yaw_deg"]]).tolist(), 0, 0.0, 0.0, 0, 1)))
        records.append((t, dataclasses.replace(CAMERA_PUSH, status_flags=CAMERA_PUSH.status_flags | int(flags[k]) << 3)))
        if new_second[k]:
            records.append((t, home))
    return records


def osd_record(row: dict[str, float]) -> OsdGeneral:
    """OSD General for one track row (missing heights/angles/speed sent as 0; velocity along the yaw)."""
    height, yaw, pitch, roll, speed = np.nan_to_num([row[name] for name in (
        "height_above_takeoff_m", "aircraft_yaw_deg", "aircraft_pitch_deg", "aircraft_roll_deg", "speed_m_s")]).tolist()
    return dataclasses.replace(OSD_PUSH, latitude_deg=float(row["lat_deg"]), longitude_deg=float(row["lon_deg"]),
                               height_above_takeoff_m=height, yaw_deg=yaw, pitch_deg=pitch, roll_deg=roll,
                               velocity_x_mps=speed * math.cos(math.radians(yaw)),
                               velocity_y_mps=speed * math.sin(math.radians(yaw)))


def write_duml_capture(track: Track, path) -> None:
    """Write :func:`duml_records` as a raw capture ``path`` + ``path.idx`` (one chunk per frame, received at its
    row's time), both files atomically."""
    records = duml_records(track)
    with atomic_capture(path) as writer:
        for seq, (t, record) in enumerate(records):
            writer.append(datetime.fromtimestamp(t, timezone.utc), t - records[0][0], encode_message(record, seq).encode())
